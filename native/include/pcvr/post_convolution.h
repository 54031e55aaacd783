/// @file post_convolution.h
/// @brief PCVR's second stage: a separable discrete filter from the stride-L subgrid to every pixel.
///
/// | filter     | 1-D weight of a node at offset t (in nodes) from the pixel | support   |
/// |------------|------------------------------------------------------------|-----------|
/// | "bilinear" | 1 - |t|  (linear interpolation of the subgrid samples)      | |t| < 1   |
/// | "gauss1.4" | exp(-1.4 t^2)                                               | |t| < 2   |
/// | "gauss2.0" | exp(-2.0 t^2)                                               | |t| < 2   |
///
/// Because the subgrid nodes coincide with pixels, each output pixel has one of L phases and the
/// filter is a table of L x 4 weights, normalised per phase so constants are preserved. Only tiles
/// near touched subgrid tiles are computed. The same call serves one X-ray image or one sheet of a
/// sheet-buffered renderer.
#pragma once

#include <string>
#include <vector>

#include "pcvr/render_control.h"
#include "pcvr/splat_grid.h"
#include "pcvr/zeroed_buffer.h"

namespace pcvr {

enum class PostFilterShape { Bilinear, Gauss14, Gauss20 };

/// Parses "bilinear", "gauss1.4" or "gauss2.0"; throws InvalidArgument listing the names.
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

private:
    int stride_;
    std::vector<float> weights_;  // [phase][tap]
    std::vector<float> by_tap_;   // [tap][phase], for the horizontal pass's contiguous loops
};

/// Row-major width x height image that the depth bands add into. Float is enough here: the many
/// small contributions were already summed in double on the splat grid; a pixel gets one value per band.
struct ImageAccumulator {
    int width = 0, height = 0;
    ZeroedBuffer<float> pixels;
    ImageAccumulator(int w, int h) : width(w), height(h), pixels(size_t(w) * h) {}
};

/// image += filter applied to grid. The grid must cover the image with PostFilter::kMarginNodes.
void post_convolve(const SplatGrid& grid, const PostFilter& filter, ImageAccumulator& image, RenderControl& control);

/// image += grid, for a stride-1 grid whose nodes are the pixels ("regular" splatting).
void add_unfiltered(const SplatGrid& grid, ImageAccumulator& image);

}  // namespace pcvr
