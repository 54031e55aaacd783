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
    out.px = camera_.pixel_x(clip.x / clip.w);
    out.py = camera_.pixel_y(clip.y / clip.w);

    // The ray through the centre's pixel, in index space: origin o, direction d (passes through c).
    const Vec3 o = o0_ + ox_ * out.px + oy_ * out.py;
    const Vec3 d = d0_ + dx_ * out.px + dy_ * out.py;
    const double dd = dot(d, d);
    const double t = dot(c - o, d) / dd;
    // Crossing points of neighbouring rays with the plane through c perpendicular to d move by
    // U per pixel in x and V per pixel in y (derivative of o + t d, projected onto the plane).
    Vec3 u = ox_ + dx_ * t, v = oy_ + dy_ * t;
    u = u - d * (dot(u, d) / dd);
    v = v - d * (dot(v, d) / dd);
    out.qxx = dot(u, u);
    out.qxy = dot(u, v);
    out.qyy = dot(v, v);

    const Vec3 wd = wd0_ + wdx_ * out.px + wdy_ * out.py;
    out.line_scale = length(wd) / std::sqrt(dd);
}

}  // namespace pcvr
