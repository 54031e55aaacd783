#include "shaded/sheet_geometry.h"

#include <algorithm>

namespace pcvr {

SheetGeometry::SheetGeometry(const Camera& camera) {
    const Mat4& w2c = camera.world_to_camera();
    auto depth_of = [&](const Vec3& p) { return -(w2c.m[2][0] * p.x + w2c.m[2][1] * p.y + w2c.m[2][2] * p.z + w2c.m[2][3]); };
    auto rate_of = [&](const Vec3& d) { return -(w2c.m[2][0] * d.x + w2c.m[2][1] * d.y + w2c.m[2][2] * d.z); };
    auto at = [&](double px, double py, Vec3& origin, Vec3& dir) {
        const Ray r = camera.pixel_ray(px, py);
        dir = r.direction / rate_of(r.direction);
        origin = r.origin - dir * depth_of(r.origin);
    };
    Vec3 o1, d1, o2, d2;
    at(0, 0, origin0, dir0);
    at(1, 0, o1, d1);
    at(0, 1, o2, d2);
    origin_dx = o1 - origin0;
    origin_dy = o2 - origin0;
    dir_dx = d1 - dir0;
    dir_dy = d2 - dir0;
    world_per_depth = 1.0 / length(Vec3{w2c.m[2][0], w2c.m[2][1], w2c.m[2][2]});
    // |direction| is convex in the pixel coordinates: largest in a corner of the image.
    longest_ray = 0;
    for (double px : {0.0, double(camera.width() - 1)})
        for (double py : {0.0, double(camera.height() - 1)}) longest_ray = std::max(longest_ray, length(direction(px, py)));
}

}  // namespace pcvr
