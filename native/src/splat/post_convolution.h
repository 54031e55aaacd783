/// @file post_convolution.h
/// @brief PCVR's second stage: a separable discrete filter from the stride-L subgrid to every pixel.
///
/// | filter     | 1-D weight of a node at offset t (in nodes) from the pixel | support   |
/// |------------|------------------------------------------------------------|-----------|
/// | "bilinear" | 1 - |t|  (linear interpolation of the subgrid samples)      | |t| < 1   |
/// | "gauss1.4" | exp(-1.4 t^2)                                               | |t| < 2   |
/// | "gauss2.0" | exp(-2.0 t^2)                                               | |t| < 2   |
/// | "catmull_rom" | Catmull-Rom cubic: interpolates, exact for quadratics (negative lobes) | |t| < 2 |
///
/// When the subgrid's stride L is a whole number of pixels, each output pixel has one of L phases and
/// the filter is a table of L x 4 weights (PostFilter), normalised per phase so constants are
/// preserved; the sheet renderer calls post_convolve_region with it on each tile of each sheet that
/// splats touched. X-ray subgrids may have any node spacing of at least one pixel (one node per
/// voxel spacing at every magnification), so post_convolve takes per-pixel weights along each axis
/// (PostFilterAxis) and goes over the image once, computing only tiles near touched subgrid tiles.
#pragma once

#include <string>
#include <vector>

#include "pcvr/render_control.h"
#include "pcvr/zeroed_buffer.h"
#include "splat/splat_grid.h"

namespace pcvr {

enum class PostFilterShape { Bilinear, Gauss14, Gauss20, CatmullRom };

/// Parses "bilinear", "gauss1.4", "gauss2.0" or "catmull_rom"; throws InvalidArgument listing the names.
PostFilterShape post_filter_from_name(const std::string& name);

class PostFilter {
public:
    static constexpr int kTaps = 4;     ///< nodes base-1 .. base+2 around a pixel
    static constexpr int kMarginNodes = 2;  ///< nodes a grid needs beyond the image

    PostFilter(PostFilterShape shape, int stride);
    int stride() const { return stride_; }
    /// Weights of nodes (base - 1 + k), k in [0, kTaps), for a pixel at phase `phase` = pixel - stride * base.
    const float* weights(int phase) const { return weights_.data() + phase * kTaps; }
    /// The weights of tap k for phases 0 .. stride - 1: one node's contribution to a run of pixels.
    const float* tap_weights(int k) const { return by_tap_.data() + size_t(k) * stride_; }
    /// Nodes a pixel reads on each side: 1 when the outer taps are always zero (bilinear), else 2.
    int reach_nodes() const;
    /// The largest total negative weight of a pixel's 4 x 4 nodes (0 for filters without negative
    /// lobes): a pixel can exceed the range of its nodes by this times the range's width.
    double overshoot() const;

private:
    int stride_;
    std::vector<float> weights_;  // [phase][tap]
    std::vector<float> by_tap_;   // [tap][phase], for the horizontal pass's contiguous loops
};

/// The filter along one image axis of `pixels` pixels, for nodes `spacing` >= 1 pixels apart (node n
/// on pixel spacing * n): per pixel the node at or before it and the weights of its four taps
/// (PostFilter's weights at whole spacings). At fractional spacings and with `pixel_mean`, the bilinear
/// filter is averaged over each pixel's area, so that every node's pixels take its spacing in weight (mass
/// is conserved); without, it is sampled at the pixel centres (render_xray's antialias=False).
class PostFilterAxis {
public:
    PostFilterAxis(PostFilterShape shape, double spacing, int pixels, bool pixel_mean = true);
    /// The node at or before pixel x; its taps are nodes node(x) - 1 .. node(x) + 2.
    int node(int x) const { return node_[size_t(x)]; }
    /// The first pixel whose node is at least n (0 before the first node, `pixels` after the last):
    /// node n's pixels are [first_pixel(n), first_pixel(n + 1)).
    int first_pixel(int n) const {
        return n <= 0 ? 0 : n >= int(first_pixel_.size()) ? first_pixel_.back() : first_pixel_[size_t(n)];
    }
    /// Tap k's weight for every pixel.
    const float* tap_weights(int k) const { return by_tap_[k].data(); }

private:
    std::vector<int> node_, first_pixel_;
    std::vector<float> by_tap_[PostFilter::kTaps];
};

/// The filter's blur along one axis for nodes `spacing` pixels apart: the variance of a pixel's weights
/// about the pixel (nodes^2), averaged over the pixels. For the bilinear filter t (1 - t) at phase t
/// ((1 - 1 / L^2) / 6 at a whole stride L), plus a pixel's box (1 / (12 spacing^2)) at fractional ones.
double post_filter_blur(PostFilterShape shape, double spacing, bool pixel_mean = true);

/// Row-major width x height image that the depth bands add into. Float is enough here: the many
/// small contributions were already summed in double on the splat grid; a pixel gets one value per band.
struct ImageAccumulator {
    int width = 0, height = 0;
    ZeroedBuffer<float> pixels;
    ImageAccumulator(int w, int h) : width(w), height(h), pixels(size_t(w) * h) {}
};

/// image += the filter of `shape` applied to grid, at the grid's node spacing (PostFilterAxis, with
/// `pixel_mean`). The grid must cover the image with PostFilter::kMarginNodes.
void post_convolve(const SplatGrid& grid, PostFilterShape shape, ImageAccumulator& image, RenderControl& control,
                   bool pixel_mean = true);

/// A sheet's nodes in float, as the sheet renderer keeps them: node (0, 0) is subgrid node
/// (node_x0, node_y0), i.e. pixel (L node_x0, L node_y0); rows `pitch` floats apart.
struct NodeSheet {
    const float* values;
    size_t pitch;
    int node_x0, node_y0;
};

/// out = (or, with `add`, +=) filter applied to `nodes`, for the pixels [x0, x0 + width) x
/// [y0, y0 + height) (image coordinates), rows `out_pitch` floats apart. The nodes must hold every
/// tap: subgrid columns floor(x0 / L) - 1 .. floor((x0 + width - 1) / L) + 2, and rows likewise.
/// `scratch` is reused.
void post_convolve_region(const NodeSheet& nodes, const PostFilter& filter, int x0, int y0, int width, int height,
                          float* out, size_t out_pitch, std::vector<float>& scratch, bool add = false);

/// image += grid, for a stride-1 grid whose nodes are the pixels ("regular" splatting).
void add_unfiltered(const SplatGrid& grid, ImageAccumulator& image);

}  // namespace pcvr
