/// @file phase_splat.h
/// @brief Orthographic splats whose windows come from a PhaseFootprintTable, eight voxels at a time.
///
/// In an orthographic view a voxel's node coordinates are an affine function of its index, and its
/// window's weights depend only on where its centre falls inside its node. The splat runs in two
/// passes over groups of eight voxels: a vector pass computes each one's window corner, phase-table
/// entry and blend coefficients (already scaled by its value), then each window is added to the
/// grid row by row. Done one voxel at a time, the chain from index to stored row (position, floor,
/// phase, blend, weights, accumulate) was long enough to leave the CPU waiting on it; split this
/// way, the second pass has only short, independent chains and the first costs an eighth per voxel.
/// PCVR's 4 x 4 window and regular splatting's (4m)^2 window take the same path.
#pragma once

#include <cstdint>

#include "splat/block_tile.h"

#include "pcvr/grid.h"
#include "splat/block_linearisation.h"
#include "pcvr/math.h"
#include "splat/phase_table.h"
#include "splat/splat_grid.h"
#include "view/view_projection.h"

namespace pcvr {

/// Where the voxels of an orthographic view land on a splat grid.
struct OrthographicMapping {
    Vec3 gx, gy;          ///< storage node coordinates per index step along i, j, k
    double bx = 0, by = 0;  ///< storage node coordinates of index (0, 0, 0)
    float amp_per_value = 1;  ///< footprint amplitude per unit of voxel value

    double node_x(const Vec3& index) const { return bx + gx.x * index.x + gx.y * index.y + gx.z * index.z; }
    double node_y(const Vec3& index) const { return by + gy.x * index.x + gy.y * index.y + gy.z * index.z; }
};

/// Splats the active, finite, non-zero voxels of `block` with the windows of `table` into `grid`,
/// clipping windows at the grid's edge. With `clip_view`, only voxels whose centre lies between its
/// clip planes count. Returns the number of voxels splatted.
uint64_t splat_block_phases(const VoxelBlock& block, const OrthographicMapping& map, const PhaseFootprintTable& table,
                            const ViewProjection* clip_view, SplatGrid& grid, SplatScratch& scratch);

/// A perspective block's voxels (block_linearisation.h): node positions lin.x / lin.w and lin.y / lin.w relative
/// to storage node (ref_x, ref_y), form and line scale as affine functions of the voxel's offset.
struct ProjectiveBlock {
    const BlockLinearisation* lin;
    int ref_x = 0, ref_y = 0;
    float density_scale = 1;
    /// The determinant of the form `table` holds (CachedPhaseTable::table_det; 0: a pixel-averaged table).
    double table_det = 0;
};

/// Whether this build splats perspective blocks with phase tables (the batched splat needs AVX2).
#if defined(__AVX2__) && defined(__FMA__)
constexpr bool kProjectivePhases = true;
#else
constexpr bool kProjectivePhases = false;
#endif

/// Splats a perspective block's active, finite, non-zero voxels with the windows of `table` (src/splat/
/// phase_table_cache.h), each at its own centre and with its own mass: a sampled table's footprint scaled by
/// sqrt(table_det / det) of the voxel's form, a pixel-averaged one's weights by the voxel's footprint integral.
/// Returns the number of voxels splatted and counts their taps into scratch.taps.
uint64_t splat_block_phases(const VoxelBlock& block, const ProjectiveBlock& projected, const PhaseFootprintTable& table,
                            SplatGrid& grid, SplatScratch& scratch);

/// The same with a pixel-averaged footprint's separable table: each voxel's window is its x row times its y
/// column (times its footprint integral), added a row of eight lanes at a time.
uint64_t splat_block_separable(const VoxelBlock& block, const ProjectiveBlock& projected, const SeparableFootprintTable& table,
                               SplatGrid& grid, SplatScratch& scratch);

}  // namespace pcvr
