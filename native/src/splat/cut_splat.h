/// @file cut_splat.h
/// @brief The voxels whose kernels a clip plane cuts, integrated along each pixel's own ray.
///
/// A footprint is the line integral of a whole kernel; a kernel that a clip plane (or a crop box's
/// face) passes through keeps only the part of each ray on the kept side, and that part changes across
/// the footprint. Where a plane is seen edge-on the kept image has a sharp edge, which no subgrid and
/// post-convolution can carry, so these voxels are not splatted into the subgrid: each pixel whose ray
/// meets the kernel gets value x P(rho, kept interval) directly, from Kernel::segment_integral (the
/// exact reference does the same for every voxel). They are a shell one kernel diameter thick along
/// the cuts, so the cost follows the cut's area, not the volume.
/// The voxels of a block that straddles a cut are sorted by split_cut_block: wholly kept ones go on
/// to the ordinary splats, cut ones here, wholly removed ones nowhere.
#pragma once

#include <cstdint>
#include <vector>

#include "pcvr/clip_region.h"
#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "pcvr/render_control.h"
#include "splat/post_convolution.h"
#include "view/view_projection.h"

namespace pcvr {

/// A voxel whose kernel a cut crosses: its index-space centre and value (times its density scale).
struct CutVoxel {
    Vec3 centre;
    double amplitude;
};

/// `block` with only the voxels whose kernels (of `radius`) lie wholly inside `clip` (index space)
/// active; the non-zero ones that straddle it are appended to `cut`.
VoxelBlock split_cut_block(const VoxelBlock& block, const ClipRegion& clip, double radius, double density_scale,
                           std::vector<CutVoxel>& cut);

/// Adds the kept line integral of each voxel's kernel to every pixel of `image` whose ray meets it
/// (voxels whose centres lie outside the camera's near and far planes are skipped, as every splat
/// does). Returns the number of pixel taps evaluated.
uint64_t splat_cut_voxels(const std::vector<CutVoxel>& voxels, const ViewProjection& view, const ClipRegion& clip,
                          const Kernel& kernel, ImageAccumulator& image, RenderControl& control);

}  // namespace pcvr
