/// @file splatter.h
/// @brief Splatting voxel blocks into a SplatGrid, with footprint tables or bilinear spreading.
///
/// | mode            | per voxel                                                        |
/// |-----------------|------------------------------------------------------------------|
/// | Footprint       | every node within the kernel's ellipse gets value * P(rho^2), P from the table |
/// | BilinearSpread  | the footprint's whole integral goes to the 2 x 2 nearest nodes with bilinear weights (Westenberg-Roerdink) |
///
/// Orthographic footprints of smooth kernels up to 64 x 64 nodes (PCVR's 4 x 4 window, and regular
/// splatting up to magnification 16) and orthographic bilinear spreading take whole windows from a
/// PhaseFootprintTable (src/splat/phase_splat.h); all others (perspective views, the box kernel, wider
/// footprints) project each voxel's own footprint and look P up in the FootprintTable per tap
/// (src/splat/footprint_splat.h). Both run eight voxels at a time.
/// Used for every splatting method: "regular" splats into a stride-1 grid (the image), "pcvr" and
/// "bilinear_spread" into the stride-L subgrid; the same code for both keeps the comparison honest.
/// It is equally usable per sheet and per tile: it only needs blocks, a view and a target grid.
/// Work is split over blocks with oneTBB in the caller's task arena; each worker accumulates into
/// its own grid, added into the target at the end.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "pcvr/render_control.h"
#include "splat/cut_splat.h"
#include "splat/splat_grid.h"
#include "view/block_plan.h"
#include "view/view_projection.h"

namespace pcvr {

enum class SplatMode { Footprint, BilinearSpread };

struct SplatParams {
    SplatMode mode = SplatMode::Footprint;
    const FootprintTable* table = nullptr;  ///< required for Footprint
    const Kernel* kernel = nullptr;         ///< required for Footprint (builds phase tables)
    double kernel_radius = 2.0;             ///< index units
    float density_scale = 1.0f;
    /// Perspective views: voxels of blocks the plan marks exact_footprints whose
    /// linearised_footprint_error exceeds this are splatted exactly (src/splat/near_eye_splat.h).
    double footprint_tolerance = std::numeric_limits<double>::infinity();
    /// Footprints narrower than a pixel are integrated over each pixel's area (src/splat/pixel_prefilter.h).
    bool antialias = true;
    /// The grid's level of detail (Grid::level): its voxels' footprints spread like the 8^level voxels
    /// they stand for (src/view/level_of_detail.h).
    int level = 0;
    /// The grid's clip region in index space (pcvr/clip_region.h), for the blocks the plan marks cut, and
    /// what splats the kernels it cuts (required with it).
    const ClipRegion* clip = nullptr;
    const CutSplatter* cuts = nullptr;
    /// Perspective views whose magnification over the volume stays within a band (a narrow field of view from
    /// afar): a few phase tables stand for all footprints (src/splat/phase_table_cache.h). A wide view meets
    /// hundreds of forms, a table each (0.1 ms), and keeps its footprints tap by tap.
    bool phase_tables = false;
};

/// Splat `blocks` of `grid_blocks` into `target`. Returns the number of voxels splatted (active, non-zero,
/// inside the clip range) and adds the window taps written to `*taps` when given. Advances `control`
/// by one unit per block and stops with Cancelled. Of the blocks the plan marks cut, the voxels whose
/// kernels straddle params.clip are splatted with their kept footprints where those are smooth at the
/// target's nodes and go to `*cut` (to be integrated per pixel) where not (src/splat/cut_splat.h); those
/// outside go nowhere.
uint64_t splat_blocks(const std::vector<VoxelBlock>& grid_blocks, const std::vector<PlannedBlock>& blocks,
                      const ViewProjection& view, const SplatParams& params, SplatGrid& target,
                      RenderControl& control, uint64_t* taps = nullptr, std::vector<CutVoxel>* cut = nullptr);

}  // namespace pcvr
