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
    if (!index_to_world.is_affine() || !index_to_world.inverse())
        throw GridError("the grid's index-to-world transform is singular or not affine");
    index_to_clip_ = camera.object_to_clip(index_to_world);
    const Vec3 w_gradient{index_to_clip_.m[3][0], index_to_clip_.m[3][1], index_to_clip_.m[3][2]};
    if (length(w_gradient) > 0) depth_axis_ = w_gradient / length(w_gradient);
    // Rays go from camera space straight to index space: a grid and a camera far from the world's
    // origin never meet in world coordinates, where their offsets would cancel imprecisely.
    const auto camera_to_index = (camera.world_to_camera() * index_to_world).inverse();
    if (!camera_to_index) throw GridError("the grid's index-to-world transform is singular in camera space");
    const Ray& r0 = camera.ray_at_origin();
    const Ray& rx = camera.ray_per_pixel_x();
    const Ray& ry = camera.ray_per_pixel_y();
    o0_ = camera_to_index->transform_point(r0.origin);
    ox_ = camera_to_index->transform_vector(rx.origin);
    oy_ = camera_to_index->transform_vector(ry.origin);
    d0_ = camera_to_index->transform_vector(r0.direction);
    dx_ = camera_to_index->transform_vector(rx.direction);
    dy_ = camera_to_index->transform_vector(ry.direction);
    eye_ = camera_to_index->transform_point(camera.eye());
    const Mat4& camera_to_world = camera.camera_to_world();
    wd0_ = camera_to_world.transform_vector(r0.direction);
    wdx_ = camera_to_world.transform_vector(rx.direction);
    wdy_ = camera_to_world.transform_vector(ry.direction);
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
}

}  // namespace pcvr
