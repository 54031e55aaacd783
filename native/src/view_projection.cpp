#include "pcvr/view_projection.h"

#include <cmath>

#include "pcvr/errors.h"

namespace pcvr {

double Footprint::min_pixels_per_voxel() const {
    // Largest eigenvalue of the form = index units^2 per pixel^2 in the least magnified direction.
    const double half_trace = 0.5 * (qxx + qyy);
    const double disc = std::sqrt(0.25 * (qxx - qyy) * (qxx - qyy) + qxy * qxy);
    return 1.0 / std::sqrt(half_trace + disc);
}

double Footprint::extent_x(double radius) const { return radius * std::sqrt(qyy / (qxx * qyy - qxy * qxy)); }
double Footprint::extent_y(double radius) const { return radius * std::sqrt(qxx / (qxx * qyy - qxy * qxy)); }
double Footprint::area_integral() const { return 1.0 / std::sqrt(qxx * qyy - qxy * qxy); }

ViewProjection::ViewProjection(const Camera& camera, const Mat4& index_to_world) : camera_(camera) {
    const auto inv = index_to_world.inverse();
    if (!index_to_world.is_affine() || !inv)
        throw GridError("the grid's index-to-world transform is singular or not affine");
    world_to_index_ = *inv;
    index_to_clip_ = camera.world_to_clip() * index_to_world;
    const Ray& r0 = camera.ray_at_origin();
    const Ray& rx = camera.ray_per_pixel_x();
    const Ray& ry = camera.ray_per_pixel_y();
    o0_ = world_to_index_.transform_point(r0.origin);
    ox_ = world_to_index_.transform_vector(rx.origin);
    oy_ = world_to_index_.transform_vector(ry.origin);
    d0_ = world_to_index_.transform_vector(r0.direction);
    dx_ = world_to_index_.transform_vector(rx.direction);
    dy_ = world_to_index_.transform_vector(ry.direction);
    wd0_ = r0.direction;
    wdx_ = rx.direction;
    wdy_ = ry.direction;
    // W^T (W d) = W^T wd: the world direction turned back by the transposed linear part.
    auto transposed_times = [&](const Vec3& w) {
        const Vec3 a = index_to_world.column(0), b = index_to_world.column(1), c = index_to_world.column(2);
        return Vec3{dot(a, w), dot(b, w), dot(c, w)};
    };
    gd0_ = transposed_times(wd0_);
    gdx_ = transposed_times(wdx_);
    gdy_ = transposed_times(wdy_);
    // Depth = -z in camera space: minus the third row of world_to_camera * index_to_world.
    const Mat4 index_to_camera = camera.world_to_camera() * index_to_world;
    depth_gradient_ = Vec3{-index_to_camera.m[2][0], -index_to_camera.m[2][1], -index_to_camera.m[2][2]};
    depth_offset_ = -index_to_camera.m[2][3];
}

bool ViewProjection::footprint(const Vec3& c, Footprint& out) const {
    const Vec4 clip = to_clip(c);
    if (!inside_clip_range(clip)) return false;
    footprint_at(c, clip, out);
    return true;
}

bool ViewProjection::footprint_unclipped(const Vec3& c, Footprint& out) const {
    const Vec4 clip = to_clip(c);
    if (!(clip.w > 0)) return false;
    footprint_at(c, clip, out);
    return true;
}

void ViewProjection::footprint_at(const Vec3& c, const Vec4& clip, Footprint& out) const {
    const FootprintLanes<double> f =
        footprint_lanes(c.x, c.y, c.z, clip.x, clip.y, clip.w, [](double v) { return std::sqrt(v); });
    out.px = f.px;
    out.py = f.py;
    out.qxx = f.qxx;
    out.qxy = f.qxy;
    out.qyy = f.qyy;
    out.line_scale = f.line_scale;
    out.depth = f.depth;
    out.depth_dx = f.depth_dx;
    out.depth_dy = f.depth_dy;
    out.distance_dx = f.distance_dx;
    out.distance_dy = f.distance_dy;
    out.depth_per_index = f.depth_per_index;
}

}  // namespace pcvr
