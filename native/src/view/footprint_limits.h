/// @file footprint_limits.h
/// @brief Where a voxel's projected footprint stops being a linearised ellipse sampled at pixel centres:
/// below a pixel per voxel (integrated over pixel areas instead, splat/pixel_prefilter.h) and near a
/// perspective eye (integrated along each ray instead, splat/near_eye_splat.h).
///
/// The block plan asks these questions of whole blocks before any splat runs (how far a block's
/// footprints reach, whether it needs exact footprints), so they live with the view, below the splats.
#pragma once

#include <limits>

#include "pcvr/grid.h"
#include "view/view_projection.h"

namespace pcvr {

/// Footprints of fewer pixels per voxel than this (in their least magnified direction) are prefiltered.
/// The tolerance keeps an exact magnification of 1 (computed as 0.9999999) on the sampled path.
constexpr double kPrefilterBelowPixelsPerVoxel = 1.0 - 1e-6;

/// How far (pixels) the prefilter widens a footprint's reach on each side: half a pixel.
constexpr double kPrefilterReach = 0.5;

inline bool prefiltered(const Footprint& f) { return f.min_pixels_per_voxel() < kPrefilterBelowPixelsPerVoxel; }

/// Whether a perspective block's footprints are integrated over pixels, all of them or none: its centre's
/// footprint is narrower than a pixel (src/splat/block_linearisation.h says why the block chooses, not each
/// voxel). The block plan (how far the block reaches) and the splats ask the same question.
inline bool block_prefiltered(const VoxelBlock& block, const ViewProjection& view) {
    const double middle = 0.5 * (VoxelBlock::kDim - 1);
    Footprint centre;
    return view.footprint_unclipped({block.origin[0] + middle, block.origin[1] + middle, block.origin[2] + middle}, centre) &&
           prefiltered(centre);
}

/// The linearised footprint's largest error relative to its peak, for kernel radius R at `depth`,
/// `lateral` distance from the axis and `line_scale_slope` (index units, ViewProjection::eye_offset):
/// (R/d) (0.4 t + 0.1 R/d + 0.2 s) with t = lateral / depth. Fitted to single voxels against exact:
/// isotropic ones on and off the axis, and 600 random anisotropic ones (scales 1/4 to 4, any
/// rotation, up to 50 degrees off the axis), all within the model (tests/stress/test_near_eye.py);
/// infinite at and behind the eye plane.
inline double linearised_footprint_error(double radius, double depth, double lateral, double line_scale_slope) {
    if (!(depth > 0)) return std::numeric_limits<double>::infinity();
    const double q = radius / depth;
    return q * (0.4 * lateral / depth + 0.1 * q + 0.2 * line_scale_slope);
}

}  // namespace pcvr
