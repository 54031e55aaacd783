/// @file near_eye_splat.h
/// @brief Exact footprints for the voxels of a perspective view whose projection is too curved to
/// linearise: near the eye, and close and far off the axis.
///
/// The splats project each voxel's kernel through the projection linearised at the voxel's centre
/// (view_projection.h). For kernel radius R at depth d and off-axis tangent t its largest error,
/// relative to the footprint's peak, measures 0.1 (R/d)^2 on the axis, where the footprint stays
/// symmetric, and 0.4 (R/d) t off it, where one side is squeezed and the other stretched; with
/// anisotropic voxels the world length per index length also changes across the footprint, which
/// takes its value at the centre (linearised_footprint_error). A kernel that reaches behind the eye has no footprint at all (every
/// ray through the eye crosses one that contains it): with the eye inside a volume the linearised
/// ellipses returned 3 to 20 times the true integral. Voxels whose error would exceed the
/// tolerance are therefore integrated along each node's own ray, as the exact reference does: rho
/// is the distance in index space from the voxel's centre to the ray through the node's pixel, and
/// the footprint table gives P(rho) (the same table as every other splat).
///
/// All rays pass through the eye e, so with w = c - e a ray of direction D meets the kernel when
/// (w . D)^2 > (|w|^2 - R^2) |D|^2. D is affine in node coordinates, which makes that a quadratic
/// in the column on each row, and its discriminant a quadratic in the row: the nodes a voxel can
/// reach are found in closed form, whether its kernel projects to an ellipse, reaches past the eye
/// plane or contains the eye.
#pragma once

#include <cstdint>
#include <limits>

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "splat/block_tile.h"
#include "splat/footprint_splat.h"
#include "splat/splat_grid.h"
#include "view/block_plan.h"
#include "view/footprint_limits.h"

namespace pcvr {

/// The bound on linearised_footprint_error that keeps a footprint within `tolerance` of its peak.
/// The box kernel's footprint has an infinite slope at its rim, where a geometric error e moves
/// values by up to sqrt(7 e) of the peak (measured, tests/stress/test_near_eye.py): it needs e below
/// tolerance^2 / 7.
inline double geometric_tolerance(double tolerance, const Kernel& kernel) {
    return kernel.smooth_footprint() ? tolerance : tolerance * tolerance / 7.0;
}

/// Splats the voxels of `block` whose linearised_footprint_error exceeds `tolerance` (a geometric
/// one) exactly, and passes the others to splat_block_footprints. Returns the number of voxels splatted.
uint64_t splat_block_near_eye(const VoxelBlock& block, const PlannedBlock& planned, const FootprintSplatParams& params,
                              double tolerance, SplatGrid& grid, SplatScratch& scratch);

}  // namespace pcvr
