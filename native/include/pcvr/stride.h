/// @file stride.h
/// @brief The subgrid stride: pixels between the nodes a voxel is splatted into, from its projected spacing.
///
/// At magnification m a voxel spans m pixels; a subgrid node per voxel spacing (stride m) keeps the
/// splat at 4 x 4 taps whatever m is, and the post-convolution fills in the pixels between nodes.
#pragma once

namespace pcvr {

/// Strides are at most this, a Camera's largest side: near a perspective eye magnifications grow
/// without bound, and post filters allocate per pixel of stride. (Bilinear spreading, which needs
/// about one node per voxel, is wrong beyond 65536 pixels per voxel: the image then shows less than
/// a voxel.)
constexpr int kMaxStride = 1 << 16;

/// The whole stride that never undersamples a projected voxel spacing of `pixels_per_voxel`.
int automatic_stride(double pixels_per_voxel);
/// The fractional stride of blocks magnified `pixels_per_voxel` in a view whose least magnified
/// block has `least` pixels per voxel: the band below it on a ladder that starts at
/// max(1, least) (a whole number when within 1e-6 of one) and grows by kStrideBandRatio. An
/// orthographic view's blocks all have `least` and one band; a perspective view's nearer blocks
/// take coarser bands, whose footprints span at most kStrideBandRatio times the 4 x 4 window's.
double fractional_stride(double pixels_per_voxel, double least);
constexpr double kStrideBandRatio = 1.189207115002721;  // 2^(1/4)
/// A perspective view's stride for blocks whose most magnified voxels have `most_pixels_per_voxel`, in a view
/// whose most magnified block has `most`: the band at or above it on a ladder that falls from max(1, most) by
/// kPerspectiveBandRatio, never below 1. Every footprint then spans at most PCVR's 4 x 4 window, whose phase
/// table a block's voxels share (src/splat/phase_table_cache.h); the nodes lie up to a band's ratio (and a
/// block's spread of magnification) more than a voxel spacing apart.
double perspective_stride(double most_pixels_per_voxel, double most);
constexpr double kPerspectiveBandRatio = 1.0905077326652577;  // 2^(1/8)
/// The stride closest to one voxel per node (for bilinear spreading).
int nearest_stride(double pixels_per_voxel);

}  // namespace pcvr
