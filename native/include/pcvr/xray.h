/// @file xray.h
/// @brief X-ray (line-integral) rendering of one or more grids: the four methods behind render_xray.
///
/// | method            | splat into              | then                                  |
/// |-------------------|-------------------------|---------------------------------------|
/// | "regular"         | the image (stride 1)    | nothing: classic footprint splatting  |
/// | "pcvr"            | the stride-L subgrid    | one separable post-convolution        |
/// | "bilinear_spread" | the stride-L subgrid, 2x2 bilinear | one separable post-convolution |
/// | "exact"           | analytic, per pixel, double precision (reference)               |
///
/// The image is the integral of the reconstructed density along each pixel's ray in world units.
/// The camera's near and far planes clip per voxel: a voxel contributes its whole footprint when its
/// centre lies between them. A grid's clip region (clip planes, crop box: pcvr/clip_region.h) cuts its
/// reconstructed field exactly: each ray integrates the kept part of every kernel (src/splat/cut_splat.h).
/// Grids are summed, so overlapping volumes add.
#pragma once

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "pcvr/attenuation_map.h"
#include "pcvr/camera.h"
#include "pcvr/clip_region.h"
#include "pcvr/grid.h"
#include "pcvr/grid_stream.h"
#include "pcvr/render_control.h"
#include "pcvr/zeroed_buffer.h"

namespace pcvr {

/// The default footprint_tolerance: a linearised footprint may be off by 4% of its peak (PCVR's
/// own post-filter is off by 30-40% of an isolated voxel's peak). Measured on a 128^3 volume at
/// 512^2 (docs/reliability.md): with the eye inside it pcvr costs 28% more than with linearised
/// footprints only (which were 28 times too bright), 20% more in a 90-degree close-up, nothing
/// from afar; 1% would cost 2.2x and 1.8x.
constexpr double kFootprintTolerance = 0.04;

/// A grid and the factor its densities are scaled by.
struct WeightedGrid {
    const Grid* grid;
    double density_scale;
    /// The grid is this level of detail of another (GridStream::level): its footprints are widened as
    /// Grid::level's are, and renders choose levels of it no further.
    int level = 0;
    /// When set, the X-ray integrates the attenuation its values map to (Hounsfield units to mu).
    const AttenuationMap* attenuation = nullptr;
    /// When set, only the part of the reconstructed field inside it is integrated (world space).
    const ClipRegion* clip = nullptr;
};

enum class XrayMethod { Regular, Pcvr, BilinearSpread, Exact };

/// Parses "regular", "pcvr", "bilinear_spread" or "exact"; throws InvalidArgument listing the names.
XrayMethod xray_method_from_name(const std::string& name);

/// How much the image may differ from the line integrals of the sampled signal in its passband:
/// "compensated" sharpens the splat grid to pay back the blur of the splat kernel and the post filter
/// (src/splat/passband.h: pcvr and regular); "paper" keeps the paper's kernel and post filter as they are.
/// Bilinear spreading and `exact` (the kernel model's reference) always render the paper's.
enum class Passband { Compensated, Paper };

/// Parses "compensated" or "paper"; throws InvalidArgument listing the names.
Passband passband_from_name(const std::string& name);

struct XrayParams {
    XrayMethod method = XrayMethod::Pcvr;
    std::string splat_kernel = "gauss1.4";
    std::string post_filter = "bilinear";
    int stride = 0;      ///< subgrid stride in pixels; 0 = automatic per depth band
    int threads = 0;     ///< 0 = all cores
    int pixel_step = 1;  ///< exact only: evaluate every step-th pixel
    /// Perspective views: voxels whose linearised footprint would be off by more than this fraction
    /// of its peak get exact per-ray footprints (0: all; infinity: none). Bilinear spreading, whose
    /// spread mass is the linearised footprint's integral, takes them too.
    double footprint_tolerance = kFootprintTolerance;
    /// Bytes the render's buffers may take (pcvr/memory_budget.h); 0: what the machine has available.
    uint64_t memory_limit = 0;
    /// Footprints narrower than a pixel are integrated over each pixel's area (src/splat/pixel_prefilter.h);
    /// false: sampled at pixel centres like `exact`'s rays.
    bool antialias = true;
    /// Level of detail (Grid::level) each grid is rendered from; -1: the coarsest whose voxels project
    /// to at most 1/32 of a pixel (src/view/level_of_detail.h), 0 without antialias. `exact` always takes level 0.
    int level = -1;
    /// Sub-pixels per pixel edge the image is splatted at and box-averaged down to: 0 automatic (zoomed
    /// out, with level -1 and antialias: src/view/level_of_detail.h), 1 none. Streams set it so that
    /// every batch takes the same; Python has no argument for it.
    int supersampling = 0;
    Passband passband = Passband::Compensated;
    /// The least and most pixels per voxel regular splatting's passband compensation takes; {0, 0}: those of
    /// the grids' boxes. Streams set it to the whole stream's, so that every batch takes the same; Python
    /// has no argument for it.
    std::pair<double, double> compensation_magnification{0.0, 0.0};
    /// A field >= 0 renders >= 0 (clear_negative_pixels); streams render their batches without (the correction is
    /// not linear: a batch's faces would show) and correct their sum instead. Python has no argument for it.
    bool keep_nonnegative = true;
};

struct XrayStats {
    uint64_t voxels_splatted = 0;
    uint64_t blocks_total = 0;
    uint64_t blocks_culled = 0;
    uint64_t blocks_clipped = 0;   ///< wholly outside their grid's clip region
    uint64_t voxels_cut = 0;       ///< kernels a clip plane seen near edge-on crosses, integrated per pixel (not in voxels_splatted)
    double min_magnification = 0;  ///< pixels per voxel over the splatted blocks
    double max_magnification = 0;
    std::vector<double> strides;   ///< pixels between subgrid nodes, one per depth band (fractional when automatic)
    uint64_t taps = 0;             ///< splat window taps written (work: taps / voxels_splatted per voxel)
    int supersampling = 1;         ///< sub-pixels per pixel edge the image was splatted at (then box-averaged)
    int level = 0;                 ///< the coarsest level of detail a grid was rendered from
    uint64_t memory_bytes = 0;     ///< the buffers' estimated peak (checked against the memory limit)
    /// With a field >= 0 (voxels times density scales): the pixels the passband compensation's ringing or a post
    /// filter's negative lobes took below zero, cleared (clear_negative_pixels).
    uint64_t pixels_negative_corrected = 0;
    bool nonnegative = true;       ///< every grid rendered was >= 0 times its density scale
    uint64_t batches = 0;          ///< renders the streamed grids took (one per batch), and one for the others
    double seconds = 0;

    /// Widen [min_magnification, max_magnification] by a plan's (lo, hi); (0, 0) is nothing in view.
    void include_magnification(double lo, double hi) {
        if (!(hi > 0)) return;
        min_magnification = min_magnification > 0 ? std::min(min_magnification, lo) : lo;
        max_magnification = std::max(max_magnification, hi);
    }
};

struct XrayImage {
    int width = 0, height = 0;
    ZeroedBuffer<float> pixels;  ///< row-major, row 0 on top
};

XrayImage render_xray(const std::vector<WeightedGrid>& grids, const Camera& camera, const XrayParams& params,
                      RenderControl& control, XrayStats* stats = nullptr);

/// An X-ray of a field >= 0 must be >= 0: sets a width x height image's pixels below zero to zero and takes what
/// that adds from the positive pixels within `radius` of each, in proportion to their values (mass stays, where
/// an undershoot has its overshoot beside it). Returns how many pixels were below zero.
uint64_t clear_negative_pixels(float* pixels, int width, int height, int radius);
inline uint64_t clear_negative_pixels(ZeroedBuffer<float>& pixels, int width, int height, int radius) {
    return clear_negative_pixels(pixels.data(), width, height, radius);
}

/// Nodes (a projected voxel spacing) from an edge that the passband compensation's ringing reaches in the
/// image: its own node and the post filter's.
constexpr double kRingingNodes = 2.0;
/// The pixels clear_negative_pixels looks around, for an image rendered with these strides and magnifications.
int ringing_reach(const XrayStats& stats);

/// A grid read from its file a batch at a time (grid_stream.h), and the factor its densities are scaled by.
struct WeightedStream {
    const GridStream* stream;
    double density_scale = 1.0;
    const AttenuationMap* attenuation = nullptr;  ///< applied to every batch (see WeightedGrid)
    const ClipRegion* clip = nullptr;             ///< see WeightedGrid
};

/// render_xray of `grids` and the streamed grids (src/xray/streamed_xray.cpp): X-ray images add, so each
/// batch is rendered as a grid of its own and the images are summed. With a memory limit, a batch's
/// voxels take half of it and the render's buffers the other half (without one, batches take
/// GridStream::kDefaultBatchBytes); progress runs over the voxels, and stats add up over the batches.
XrayImage render_xray(const std::vector<WeightedGrid>& grids, const std::vector<WeightedStream>& streams,
                      const Camera& camera, const XrayParams& params, RenderControl& control, XrayStats* stats = nullptr);

/// Smallest and largest pixels per voxel over the grid's blocks in view (0, 0 when nothing is in view).
std::pair<double, double> effective_magnification(const Grid& grid, const Camera& camera);
/// The same for a streamed grid, whose values (and so blocks) are in its file: over its active box's corners.
std::pair<double, double> effective_magnification(const GridStream& stream, const Camera& camera);

}  // namespace pcvr
