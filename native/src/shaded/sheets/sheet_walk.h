/// @file sheet_walk.h
/// @brief One tile's front-to-back walk through its sheets: splat, post-convolve, classify, shade,
/// composite, sheet after sheet, until the tile is done or opaque.
///
/// Before the samples from sheet s towards s + 1 are composited, every voxel whose kernel reaches sheet
/// s + 2 has been splatted: voxels are taken from the tile's blocks in depth order, a block's voxels in
/// the order of SlabView::depth_order, as the splat front moves on. Sheet s + 2 is then post-convolved
/// to the tile's pixels plus a halo of one subgrid node (for the in-sheet gradient), and the samples
/// are classified, shaded and composited into the tile: with samples_per_sheet > 1 the density along
/// the ray is the Catmull-Rom cubic through sheets s - 1 to s + 2, so that a surface crossing the sheets
/// is not cut into terraces. Only four post-convolved sheets and a ring of node sheets per grid are
/// alive at a time. Runs of sheets that no splat reaches are jumped over. The occlusion map is rebuilt
/// as pixels become opaque, and splats that can only reach opaque pixels are skipped; a tile whose
/// every pixel is opaque stops.
/// A SheetWalker holds one thread's scratch memory and is reused tile after tile.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/render_control.h"
#include "pcvr/shading.h"
#include "pcvr/transfer_function.h"
#include "shaded/classify/preintegration.h"
#include "shaded/classify/sample_clip.h"
#include "shaded/sheets/compositing.h"
#include "shaded/sheets/occlusion_map.h"
#include "shaded/sheets/sample_ownership.h"
#include "shaded/sheets/sheet_buffer.h"
#include "shaded/sheets/sheet_geometry.h"
#include "shaded/sheets/sheet_sampling.h"
#include "shaded/sheets/slab_splat.h"
#include "splat/post_convolution.h"
#include "view/tile_set.h"

namespace pcvr {

/// One grid as the walk sees it: what classifies its sheets, and the finest subgrid stride of its
/// layers (the step of its in-sheet gradient).
struct WalkGrid {
    const ClassificationTable* classification;  ///< null for MIP
    const Shader* shader;                       ///< null for MIP
    int gradient_step;
    float background;  ///< added to the sheets' densities (SlabSplatParams::background), scaled
    const SampleClip* clip = nullptr;  ///< the grid's clip region, relative to SheetGeometry::origin0
    /// Non-null: the stretches between samples are pre-integrated (classification's transfer function).
    const PreintegrationTable* preintegration = nullptr;
};

/// The blocks of one grid splatted at one subgrid stride: a perspective view splats nearer blocks,
/// magnified more, at a coarser stride (depth bands, as for X-ray); each layer has its own rings, and
/// its sheets are post-convolved into the grid's pixel sheets, where the layers add up.
struct WalkLayer {
    const SlabView* view;
    uint32_t grid;     ///< into SheetWalkSetup::grids
    PostFilter filter; ///< at the view's stride
    bool post_convolve;  ///< false (regular): the ring's nodes are the pixels
    /// Non-null: the layer's sheets are sampled (sheet_sampling.h), not splatted; its blocks only say
    /// where. Stride 1, the grid's only layer.
    const SheetSampler* sampler = nullptr;
};

struct SheetWalkSetup {
    std::vector<WalkGrid> grids;
    std::vector<WalkLayer> layers;  ///< TileBlock::grid indexes these
    const TileSet* tiles = nullptr;
    SheetLattice sheets;
    const SheetGeometry* geometry = nullptr;
    bool mip = false;  ///< maximum intensity projection: no classification, no shading
    float opacity_cutoff = 0.99f;
    int samples_per_sheet = 1;  ///< classified samples from one sheet to the next (1: at each sheet)
    /// Each stretch between consecutive samples is classified from its two ends (WalkGrid::preintegration):
    /// the stretches then lie between the samples, sheet s's middle to s + 1's in samples_per_sheet steps.
    bool preintegrated = false;
    /// Whether a sample reads sheets beyond s (s - 1 to s + 2): several per sheet, or pre-integrated stretches.
    bool between_sheets() const { return !mip && (samples_per_sheet > 1 || preintegrated); }
    int width = 0, height = 0;
    float near_depth = 0, far_depth = INFINITY;  ///< the clip planes, in camera-space depth
    float mip_background = 0;  ///< MIP: the maximum where no voxel reaches (see mip_background)
    /// Non-null: one brick of a bricked render (shaded/bricks): only the samples it owns count, and each
    /// tile continues the image already there (colour, opacity, depth or maximum) instead of starting empty.
    const SampleOwnership* owned = nullptr;

    int8x within_clip(float8 depth) const { return (depth >= near_depth) & (depth <= far_depth); }
    /// True when every pixel's stretch of ray from u - half to u + half (sheet parameter) lies between
    /// the clip planes, so that no sample needs its share.
    bool within_clip_everywhere(double u, double half) const;
    /// The share of the ray from depth - half_extent to depth + half_extent between the clip planes:
    /// spherical sheets cross the planes, and a sample half in front of the near plane counts half.
    float8 clip_share(float8 depth, float8 half_extent) const {
        const float8 covered = min8(depth + half_extent, broadcast8(far_depth)) - max8(depth - half_extent, broadcast8(near_depth));
        return max8(broadcast8(0.0f), min8(broadcast8(1.0f), covered / (2.0f * half_extent)));
    }
};

struct WalkStats {
    uint64_t voxels_splatted = 0, voxels_occluded = 0, taps = 0;
    uint64_t samples_classified = 0, samples_shaded = 0;  ///< pixel-samples: classified, and with extinction (lit, composited)
    uint64_t tiles_terminated = 0, tile_sheets_composited = 0, tile_sheets_skipped = 0;
    uint64_t sheet_samples = 0, sheet_samples_skipped = 0;  ///< sampled layers' values interpolated, and left 0 (8 a vector)
    uint32_t sampled_strides = 0;  ///< bit L set where a sampled sheet took subgrid stride L (SheetSampler::stride_at)
    double seconds_sampling = 0;
    double seconds_splat = 0, seconds_post_convolution = 0, seconds_shading = 0;
    int64_t first_sheet = INT64_MAX, last_sheet = INT64_MIN;

    void add(const WalkStats& o);
};

class SheetWalker {
public:
    SheetWalker();
    ~SheetWalker();
    /// Renders tile `tile` into `image`: RGBA (4 floats per pixel) for shaded renders, one float per
    /// pixel for MIP; row-major over the whole image.
    /// `depth` (optional, one float per pixel): where the opacity first reached one half.
    void render(const SheetWalkSetup& setup, size_t tile, float* image, float* depth, WalkStats& stats, RenderControl& control);

private:
    struct GridState;
    struct LayerState;
    static constexpr int kMostSources = 64;  ///< grids composited at one sample; more are left out
    /// Classifies, shades and composites the sample t of the way from sheet s to s + 1 into the tile;
    /// returns how many pixels became opaque.
    size_t composite_sample(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s, float t, int samples);
    /// composite_sample compiled for point-sampled or pre-integrated classification, so that the point path, the
    /// default, carries none of the pre-integrated one's selects in its inner loop; and for at most `MostSources`
    /// grids at a sample: with one, its per-source arrays are single values the compiler keeps in registers.
    template <bool Preintegrated, int MostSources>
    size_t composite_sample_as(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s, float t, int samples);
    void take_maximum(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s);
    /// A brick's tile starts from the image the bricks before it left (SheetWalkSetup::owned); returns
    /// how many of its pixels are opaque already.
    size_t continue_image(const SheetWalkSetup& setup, const PixelRect& rect, const float* image, const float* depth);
    struct Active {
        size_t entry;  // into the tile's blocks
        int next_rank;
    };
    /// Fills sampled layer `layer`'s share of sheet t into its grid's slot: the cells the active blocks
    /// of the layer reach on the sheet, less the vectors of eight pixels that only opaque pixels read
    /// (`some_opaque`: whether the tile has any).
    void sample_sheet(const SheetWalkSetup& setup, uint32_t layer, int64_t t, const std::vector<TileBlock>& blocks,
                      const std::vector<Active>& active, const PixelRect& rect, bool some_opaque, WalkStats& stats);
    /// sample_sheet's sheets of subgrid stride L > 1 (SheetSampler::stride_at): the nodes that the marked
    /// cells read (`read(x, y)`: whether slot pixels x .. x + 7 of row y are read), sampled, then
    /// post-convolved to those cells' pixels in `slot`.
    template <class Read>
    void sample_subgrid(const SheetWalkSetup& setup, const SheetSampler& sampler, int L, double middle, float spacing, GridState& g,
                        const Read& read, float* slot, Box& box, WalkStats& stats);

    std::vector<std::unique_ptr<GridState>> grids_;
    std::vector<std::unique_ptr<LayerState>> layers_;
    // The tile's accumulated colour and opacity (premultiplied), or its maximum density, one plane
    // per channel, rows padded to whole vectors of eight pixels.
    size_t row_pitch_ = 0;
    std::vector<float> red_, green_, blue_, alpha_, depth_;
    std::vector<float> maximum_;
    std::vector<uint8_t> cell_shows_[kMostSources];  // composite_sample: per source, per cell of its grid, whether a value there may be visible
    OpenPixels open_pixels_;  // the tile's pixels not yet opaque, for every layer's occlusion map
    std::vector<uint8_t> sample_cells_;  // sample_sheet: per cell of the grid's slot, whether to sample it
    std::vector<uint8_t> node_wanted_;   // sample_subgrid: per node of the sheet's subgrid, whether a wanted pixel reads it
    std::vector<float> nodes_;           // sample_subgrid: the sampled nodes (0 where none is wanted)
    std::vector<uint8_t> row_may_show_;  // composite_sample: per vector of a row of the box, whether a cell it meets may show
    std::vector<uint8_t> may_show_;  // composite_sample: per vector of the sheet's box, whether a sample there may be visible
    std::vector<float> scratch_;
    uint64_t samples_classified_ = 0, samples_shaded_ = 0;  // this tile's, for WalkStats
};

}  // namespace pcvr
