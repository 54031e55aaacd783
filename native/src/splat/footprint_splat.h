/// @file footprint_splat.h
/// @brief Splats in which every voxel has its own footprint, eight voxels at a time.
///
/// Perspective views (a footprint's size and shape change with depth and position), the box
/// kernel, whose rim a phase table would blur, and footprints too wide to tabulate. A vector pass
/// projects eight voxels at once in double precision with ViewProjection's own formula (centre,
/// clip test, quadratic form, line scale) and turns them into node units of the target grid; then
/// each footprint is added row by row, its weights gathered from the FootprintTable eight taps at
/// a time: into the block's tile (block_tile.h) when the block is dense and its footprints fit one,
/// else straight into the grid. Perspective blocks far enough from the eye take their footprints
/// from the block's linearised projection instead, in float (block_linearisation.h), and their windows from the
/// phase table of the block's footprint where one stands for it (phase_table_cache.h), as orthographic voxels do.
/// Bilinear spreading takes the same pass and puts each footprint's
/// integral on its 2 x 2 nearest nodes. Footprints narrower than a pixel are integrated over each
/// pixel's area instead, in every mode (pixel_prefilter.h).
#pragma once

#include <cstdint>

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "splat/block_tile.h"
#include "splat/splat_grid.h"
#include "view/block_plan.h"
#include "view/view_projection.h"

namespace pcvr {

struct FootprintSplatParams {
    const ViewProjection* view = nullptr;
    const FootprintTable* table = nullptr;
    double kernel_radius = 2.0;   ///< index units
    double kernel_variance = 0.35;  ///< per axis, index units^2: the prefilter's Gaussian (pixel_prefilter.h)
    float density_scale = 1.0f;
    bool bilinear_spread = false;  ///< each footprint's integral to its 2 x 2 nearest nodes instead
    bool antialias = true;         ///< footprints narrower than a pixel integrated over pixels (pixel_prefilter.h)
    /// With the kernel, perspective blocks whose footprints a phase table can stand for take their windows from
    /// one (src/splat/phase_table_cache.h); the grid's level of detail sets the prefilter's reach.
    const Kernel* kernel = nullptr;
    bool phase_tables = false;  ///< the view's footprints are alike enough to share a few tables (SplatParams)
    int level = 0;
};

/// Splats the active, finite, non-zero voxels of `block` whose centres lie between the clip planes
/// into `grid`. `planned` bounds what the block can touch. Returns the number of voxels splatted.
uint64_t splat_block_footprints(const VoxelBlock& block, const PlannedBlock& planned, const FootprintSplatParams& params,
                                SplatGrid& grid, SplatScratch& scratch);

}  // namespace pcvr
