/// @file sample_ownership.h
/// @brief Which samples one brick of a bricked render owns (shaded/bricked_render.cpp): those whose
/// position, in the bricked grid's index space, lies in the brick's half-open box [lo, hi).
///
/// Bricks that tile index space own every sample exactly once: a sample's index position is computed
/// by the same float operations in every brick's render (the same camera, the same sheets), so one on
/// a shared face fails `< hi` in one brick exactly where it passes `>= lo` in the next. Rendered one
/// after another in visibility order, each continuing the image the ones before left, the bricks then
/// composite each sample once and in the order of the whole grid's walk.
#pragma once

#include <array>

#include "pcvr/lanes.h"
#include "pcvr/math.h"
#include "view/brick_order.h"

namespace pcvr {

class SampleOwnership {
public:
    /// `box` in the index space of `index_to_world`; positions passed in are relative to `origin`.
    SampleOwnership(const IndexBox& box, const Mat4& index_to_world, const Vec3& origin) {
        const Mat4 to_index = *index_to_world.inverse();
        const Vec3 at_origin = to_index.transform_point(origin);
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) rows_[a][b] = float(to_index.m[a][b]);
            offset_[a] = float(at_origin[a]);
            lo_[a] = float(box.lo[a]), hi_[a] = float(box.hi[a]);
        }
    }

    /// Per lane: whether the brick owns the sample at `position` (relative to the origin).
    int8x owns(const Vec3x8& position) const {
        int8x owned = position.x == position.x;
        for (int a = 0; a < 3; ++a) {
            const float8 index = position.x * rows_[a][0] + position.y * rows_[a][1] + position.z * rows_[a][2] + offset_[a];
            owned = owned & (index >= lo_[a]) & (index < hi_[a]);
        }
        return owned;
    }

private:
    float rows_[3][3];
    float offset_[3];
    float lo_[3], hi_[3];
};

}  // namespace pcvr
