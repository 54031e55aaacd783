#include "pcvr/block_plan.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pcvr {

int automatic_stride(double pixels_per_voxel) {
    // The small tolerance keeps an exact magnification of 4 (computed as 3.9999999) at stride 4.
    return std::max(1, int(std::floor(pixels_per_voxel + 1e-6)));
}

int nearest_stride(double pixels_per_voxel) { return std::max(1, int(std::lround(pixels_per_voxel))); }

namespace {

enum ClipSide : int { kInside = 0, kBeforeNear = 1, kBeyondFar = 2 };

// The near and far planes are half-spaces in homogeneous clip coordinates (z + w >= 0, w - z >= 0),
// which makes "all corners beyond the same plane" a valid test for the whole block.
int clip_side(const Vec4& c) {
    if (c.z + c.w < 0 || c.w <= 0) return kBeforeNear;
    if (c.w - c.z < 0) return kBeyondFar;
    return kInside;
}

}  // namespace

BlockPlan plan_blocks(const std::vector<VoxelBlock>& blocks, const ViewProjection& view, const BlockPlanParams& params) {
    BlockPlan plan;
    plan.blocks_total = blocks.size();
    const Camera& cam = view.camera();
    double mag_min = std::numeric_limits<double>::infinity(), mag_max = 0;

    for (uint32_t index = 0; index < blocks.size(); ++index) {
        const VoxelBlock& block = blocks[index];
        int sides_or = 0, sides_and = ~0;
        bool all_projectable = true;
        double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
        double ext_x = 0, ext_y = 0, block_mag_min = 1e300, block_mag_max = 0;
        for (int corner = 0; corner < 8; ++corner) {
            const Vec3 p{double(block.origin[0] + ((corner & 1) ? VoxelBlock::kDim - 1 : 0)),
                         double(block.origin[1] + ((corner & 2) ? VoxelBlock::kDim - 1 : 0)),
                         double(block.origin[2] + ((corner & 4) ? VoxelBlock::kDim - 1 : 0))};
            const Vec4 clip = view.to_clip(p);
            const int side = clip_side(clip);
            sides_or |= side;
            sides_and &= side;
            Footprint fp;
            if (clip.w <= 0 || !view.footprint_unclipped(p, fp)) {
                all_projectable = false;
                continue;
            }
            x0 = std::min(x0, fp.px);
            x1 = std::max(x1, fp.px);
            y0 = std::min(y0, fp.py);
            y1 = std::max(y1, fp.py);
            ext_x = std::max(ext_x, fp.extent_x(params.kernel_radius));
            ext_y = std::max(ext_y, fp.extent_y(params.kernel_radius));
            const double m = fp.min_pixels_per_voxel();
            block_mag_min = std::min(block_mag_min, m);
            block_mag_max = std::max(block_mag_max, m);
        }
        // Wholly before the near plane or beyond the far plane.
        if (sides_and != kInside && (sides_and & (kBeforeNear | kBeyondFar))) {
            ++plan.blocks_culled;
            continue;
        }
        int stride = 1;
        if (params.fixed_stride > 0)
            stride = params.fixed_stride;
        else if (block_mag_max > 0)
            stride = params.nearest_stride ? nearest_stride(0.5 * (block_mag_min + block_mag_max)) : automatic_stride(block_mag_min);
        if (all_projectable) {
            const double margin = double(params.margin_nodes) * stride;
            if (x1 + ext_x < -margin || x0 - ext_x > cam.width() - 1 + margin || y1 + ext_y < -margin ||
                y0 - ext_y > cam.height() - 1 + margin) {
                ++plan.blocks_culled;
                continue;
            }
        }
        if (block_mag_max > 0) {
            mag_min = std::min(mag_min, block_mag_min);
            mag_max = std::max(mag_max, block_mag_max);
        }
        PlannedBlock planned{index, sides_or != kInside, -1e30f, -1e30f, 1e30f, 1e30f};
        if (all_projectable) {
            planned.min_x = float(x0 - ext_x);
            planned.min_y = float(y0 - ext_y);
            planned.max_x = float(x1 + ext_x);
            planned.max_y = float(y1 + ext_y);
        }
        plan.by_stride[stride].push_back(planned);
    }
    if (mag_max > 0) {
        plan.min_magnification = mag_min;
        plan.max_magnification = mag_max;
    }
    return plan;
}

}  // namespace pcvr
