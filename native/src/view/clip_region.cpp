#include "pcvr/clip_region.h"

#include <cmath>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

ClipRegion ClipRegion::from(const std::vector<ClipPlane>& planes, const Mat4* world_to_box) {
    ClipRegion region;
    for (size_t k = 0; k < planes.size(); ++k) {
        const ClipPlane& p = planes[k];
        const std::string name = "clip plane " + std::to_string(k);
        if (!finite(p.normal) || !std::isfinite(p.offset)) throw InvalidArgument(name + ": its numbers must be finite");
        if (!(length(p.normal) > 0)) throw InvalidArgument(name + ": its normal (a, b, c) is zero");
        region.planes_.push_back(p);
    }
    if (world_to_box) {
        const Mat4& m = *world_to_box;
        if (!m.is_finite()) throw InvalidArgument("clip_box: the world-to-box matrix must be finite");
        if (!m.is_affine()) throw InvalidArgument("clip_box: the world-to-box matrix must be affine (last row 0, 0, 0, 1)");
        if (!m.inverse()) throw InvalidArgument("clip_box: the world-to-box matrix is singular (an empty box)");
        // Row k of M gives box coordinate k: -1 <= row . p + t_k <= 1 is two planes.
        for (int k = 0; k < 3; ++k) {
            const Vec3 row{m.m[k][0], m.m[k][1], m.m[k][2]};
            region.planes_.push_back({row, 1.0 + m.m[k][3]});
            region.planes_.push_back({-row, 1.0 - m.m[k][3]});
        }
    }
    return region;
}

ClipRegion ClipRegion::in_index_space(const Mat4& index_to_world) const {
    ClipRegion out;
    const Vec3 origin = index_to_world.transform_point({0, 0, 0});
    for (const ClipPlane& p : planes_) {
        // n . (A x + o) + d = (A^T n) . x + (n . o + d), divided by |A^T n| to measure index units.
        const Vec3 n{dot(p.normal, index_to_world.column(0)), dot(p.normal, index_to_world.column(1)),
                     dot(p.normal, index_to_world.column(2))};
        const double scale = 1.0 / length(n);
        out.planes_.push_back({n * scale, (dot(p.normal, origin) + p.offset) * scale});
    }
    return out;
}

RayInterval ClipRegion::ray_interval(const Vec3& origin, const Vec3& direction, double lo, double hi) const {
    for (const ClipPlane& p : planes_) {
        const double value = p.at(origin), rate = dot(p.normal, direction);
        if (rate > 0)
            lo = std::max(lo, -value / rate);
        else if (rate < 0)
            hi = std::min(hi, -value / rate);
        else if (value < 0)
            return {1.0, 0.0};
    }
    return {lo, hi};
}

ClipSide ClipRegion::sphere_side(const Vec3& centre, double radius) const {
    ClipSide side = ClipSide::Inside;
    for (const ClipPlane& p : planes_) {
        const double distance = p.at(centre);
        if (distance <= -radius) return ClipSide::Outside;
        if (distance < radius) side = ClipSide::Straddles;
    }
    return side;
}

ClipSide ClipRegion::box_side(const Vec3& lo, const Vec3& hi, double radius) const {
    const Vec3 centre = (lo + hi) * 0.5, half = (hi - lo) * 0.5;
    ClipSide side = ClipSide::Inside;
    for (const ClipPlane& p : planes_) {
        // The box's reach along the normal (index-space planes are unit).
        const double reach = std::abs(p.normal.x) * half.x + std::abs(p.normal.y) * half.y + std::abs(p.normal.z) * half.z +
                             radius * length(p.normal);
        const double distance = p.at(centre);
        if (distance <= -reach) return ClipSide::Outside;
        if (distance < reach) side = ClipSide::Straddles;
    }
    return side;
}

}  // namespace pcvr
