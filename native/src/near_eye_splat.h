/// @file near_eye_splat.h
/// @brief Exact footprints for the voxels of a perspective view that lie close to the eye.
///
/// The splats project each voxel's kernel through the projection linearised at the voxel's centre
/// (view_projection.h). Its relative error grows like (R / d)^2 for kernel radius R at depth d
/// (measured 0.8 (R / d)^2: 1% at 9 R, 5% at 4 R), a kernel that reaches behind the eye has no
/// footprint at all (every ray through the eye crosses one that contains it), and with the eye
/// inside a volume the linearised ellipses returned 3 to 20 times the true integral. Voxels less
/// than `near_distance` deep (ViewProjection::depth) are therefore integrated along each node's
/// own ray, as the exact reference does: rho is the
/// distance in index space from the voxel's centre to the ray through the node's pixel, and the
/// footprint table gives P(rho) (the same table as every other splat).
///
/// All rays pass through the eye e, so with w = c - e a ray of direction D meets the kernel when
/// (w . D)^2 > (|w|^2 - R^2) |D|^2. D is affine in node coordinates, which makes that a quadratic
/// in the column on each row, and its discriminant a quadratic in the row: the nodes a voxel can
/// reach are found in closed form, whether its kernel projects to an ellipse, reaches past the eye
/// plane or contains the eye.
#pragma once

#include <cstdint>

#include "block_tile.h"
#include "footprint_splat.h"
#include "pcvr/block_plan.h"
#include "pcvr/grid.h"
#include "pcvr/splat_grid.h"

namespace pcvr {

/// Splats the voxels of `block` less than `near_distance` deep (index units) exactly and passes the
/// others to splat_block_footprints. Returns the number of voxels splatted.
uint64_t splat_block_near_eye(const VoxelBlock& block, const PlannedBlock& planned, const FootprintSplatParams& params,
                              double near_distance, SplatGrid& grid, SplatScratch& scratch);

}  // namespace pcvr
