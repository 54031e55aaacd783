#include "view/block_plan.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "view/footprint_limits.h"

namespace pcvr {

namespace {

enum ClipRangeSide : int { kInside = 0, kBeforeNear = 1, kBeyondFar = 2 };

// The near and far planes are half-spaces in homogeneous clip coordinates (z + w >= 0, w - z >= 0),
// which makes "all corners beyond the same plane" a valid test for the whole block.
int clip_side(const Vec4& c) {
    if (c.z + c.w < 0 || c.w <= 0) return kBeforeNear;
    if (c.w - c.z < 0) return kBeyondFar;
    return kInside;
}

/// Whether a voxel of the block may have a linearised footprint off by more than `tolerance`.
/// Depth is affine and the distance from the axis convex, so the corners bound both; the line
/// scale's slope is bounded over all directions.
bool needs_exact_footprints(const VoxelBlock& block, const ViewProjection& view, double radius, double tolerance) {
    if (view.orthographic() || tolerance == std::numeric_limits<double>::infinity()) return false;
    double depth = std::numeric_limits<double>::infinity(), lateral = 0;
    for (int corner = 0; corner < 8; ++corner) {
        const ViewProjection::EyeOffset at = view.eye_offset({double(block.origin[0] + ((corner & 1) ? VoxelBlock::kDim - 1 : 0)),
                                                              double(block.origin[1] + ((corner & 2) ? VoxelBlock::kDim - 1 : 0)),
                                                              double(block.origin[2] + ((corner & 4) ? VoxelBlock::kDim - 1 : 0))});
        depth = std::min(depth, at.depth);
        lateral = std::max(lateral, at.lateral);
    }
    return linearised_footprint_error(radius, depth, lateral, view.max_line_scale_slope()) > tolerance;
}

bool wants_fractional_strides(const BlockPlanParams& params) {
    return params.fractional_strides && params.fixed_stride == 0 && !params.nearest_stride;
}

/// What the plan decides about one block.
struct BlockDecision {
    bool culled = false;
    bool clipped = false;  // culled by BlockPlanParams::clip
    double stride = 1;  // fractional strides are set once the least magnification is known
    double mag_min = 0, mag_max = 0;  // pixels per voxel over its corners (0: none projectable)
    PlannedBlock planned{};
};

/// The corners of a block: clip sides, projected bounds, footprint extents and magnifications.
/// `shared` is the footprint every voxel has in an orthographic view (its shape does not depend on
/// position there), which saves evaluating it at each corner.
BlockDecision decide(uint32_t index, const VoxelBlock& block, const ViewProjection& view, const BlockPlanParams& params,
                     const Footprint* shared) {
    const Camera& cam = view.camera();
    int sides_or = 0, sides_and = ~0;
    bool all_projectable = true;
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    double ext_x = 0, ext_y = 0, mag_min = 1e300, mag_max = 0;
    // A perspective block whose centre is narrower than a pixel integrates all its footprints over pixels.
    const bool block_narrow = !shared && block_prefiltered(block, view);
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p{double(block.origin[0] + ((corner & 1) ? VoxelBlock::kDim - 1 : 0)),
                     double(block.origin[1] + ((corner & 2) ? VoxelBlock::kDim - 1 : 0)),
                     double(block.origin[2] + ((corner & 4) ? VoxelBlock::kDim - 1 : 0))};
        const Vec4 clip = view.to_clip(p);
        const int side = clip_side(clip);
        sides_or |= side;
        sides_and &= side;
        Footprint local;
        if (!(clip.w > 0) || (!shared && !view.footprint_unclipped(p, local))) {
            all_projectable = false;
            continue;
        }
        const Footprint& fp = shared ? *shared : local;
        const double px = shared ? cam.pixel_x(clip.x / clip.w) : fp.px, py = shared ? cam.pixel_y(clip.y / clip.w) : fp.py;
        x0 = std::min(x0, px);
        x1 = std::max(x1, px);
        y0 = std::min(y0, py);
        y1 = std::max(y1, py);
        if (shared && corner > 0) continue;  // the same shape at every corner
        const double reach = block_narrow || prefiltered(fp) ? kPrefilterReach : 0.0;  // integrated over whole pixels
        ext_x = std::max(ext_x, fp.extent_x(params.kernel_radius) + reach);
        ext_y = std::max(ext_y, fp.extent_y(params.kernel_radius) + reach);
        const double m = fp.min_pixels_per_voxel();
        mag_min = std::min(mag_min, m);
        mag_max = std::max(mag_max, m);
    }
    BlockDecision d;
    const ClipSide cut_side = params.clip ? params.clip->box_side(
                                                {double(block.origin[0]), double(block.origin[1]), double(block.origin[2])},
                                                {double(block.origin[0] + VoxelBlock::kDim - 1), double(block.origin[1] + VoxelBlock::kDim - 1),
                                                 double(block.origin[2] + VoxelBlock::kDim - 1)},
                                                params.kernel_radius)
                                          : ClipSide::Inside;
    if (cut_side == ClipSide::Outside) {
        d.culled = d.clipped = true;
        return d;
    }
    // Wholly before the near plane or beyond the far plane.
    if (params.clip_planes && sides_and != kInside && (sides_and & (kBeforeNear | kBeyondFar))) {
        d.culled = true;
        return d;
    }
    if (params.fixed_stride > 0)
        d.stride = params.fixed_stride;
    else if (mag_max > 0 && wants_fractional_strides(params))  // at least its band's, for the margin below
        d.stride = std::clamp(std::max(mag_min, view.orthographic() ? 0.0 : mag_max * kPerspectiveBandRatio), 1.0, double(kMaxStride));
    else if (mag_max > 0)
        d.stride = params.nearest_stride ? nearest_stride(0.5 * (mag_min + mag_max)) : automatic_stride(mag_min);
    const bool exact = needs_exact_footprints(block, view, params.kernel_radius, params.footprint_tolerance);
    if (all_projectable && !exact) {
        const double margin = double(params.margin_nodes) * d.stride;
        if (x1 + ext_x < -margin || x0 - ext_x > cam.width() - 1 + margin || y1 + ext_y < -margin ||
            y0 - ext_y > cam.height() - 1 + margin) {
            d.culled = true;
            return d;
        }
    }
    if (mag_max > 0) {
        d.mag_min = mag_min;
        d.mag_max = mag_max;
    }
    d.planned = {index, sides_or != kInside, exact, cut_side == ClipSide::Straddles, -1e30f, -1e30f, 1e30f, 1e30f};
    if (all_projectable && !exact) {
        d.planned.min_x = float(x0 - ext_x);
        d.planned.min_y = float(y0 - ext_y);
        d.planned.max_x = float(x1 + ext_x);
        d.planned.max_y = float(y1 + ext_y);
    }
    return d;
}

}  // namespace

BlockPlan plan_blocks(const std::vector<VoxelBlock>& blocks, const ViewProjection& view, const BlockPlanParams& params,
                      const RenderControl* control) {
    const bool fractional = wants_fractional_strides(params);
    std::optional<Footprint> shared;
    if (view.orthographic()) {
        Footprint f;
        if (view.footprint_unclipped({0, 0, 0}, f)) shared = f;
    }
    // Decided in parallel (a large grid has hundreds of thousands of blocks), gathered in block order.
    std::vector<BlockDecision> decisions(blocks.size());
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(blocks.size()), 1024), [&](const tbb::blocked_range<uint32_t>& r) {
        if (control) control->throw_if_cancelled();
        for (uint32_t index = r.begin(); index != r.end(); ++index)
            decisions[index] = decide(index, blocks[index], view, params, shared ? &*shared : nullptr);
    });

    BlockPlan plan;
    plan.blocks_total = blocks.size();
    double mag_min = std::numeric_limits<double>::infinity(), mag_max = 0;
    for (const BlockDecision& d : decisions) {
        if (d.culled) {
            ++(d.clipped ? plan.blocks_clipped : plan.blocks_culled);
            continue;
        }
        if (d.mag_max > 0) {
            mag_min = std::min(mag_min, d.mag_min);
            mag_max = std::max(mag_max, d.mag_max);
        }
    }
    for (const BlockDecision& d : decisions) {
        if (d.culled) continue;
        // Blocks near a perspective eye, splatted ray by ray (near_eye_splat.h), keep the ladder up from the least
        // magnification: their most magnified corners may lie at the eye.
        const bool from_most = !view.orthographic() && !d.planned.exact_footprints;
        const double stride = !(fractional && d.mag_max > 0) ? d.stride
                              : from_most                   ? perspective_stride(d.mag_max, mag_max)
                                                            : fractional_stride(d.mag_min, mag_min);
        plan.by_stride[stride].push_back(d.planned);
    }
    if (mag_max > 0) {
        plan.min_magnification = mag_min;
        plan.max_magnification = mag_max;
    }
    return plan;
}

}  // namespace pcvr
