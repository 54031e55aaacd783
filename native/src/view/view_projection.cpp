#include "view/view_projection.h"

#include <algorithm>
#include <cmath>
#include <utility>

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

namespace {

/// Smallest and largest eigenvalue of a symmetric positive definite 3x3 matrix (rows), by the
/// trigonometric solution of its characteristic cubic.
std::pair<double, double> metric_eigenvalue_range(const Vec3 (&a)[3]) {
    const double off = a[0].y * a[0].y + a[0].z * a[0].z + a[1].z * a[1].z;
    const double q = (a[0].x + a[1].y + a[2].z) / 3.0;
    if (off <= 0) return {std::min({a[0].x, a[1].y, a[2].z}), std::max({a[0].x, a[1].y, a[2].z})};
    const double p2 = (a[0].x - q) * (a[0].x - q) + (a[1].y - q) * (a[1].y - q) + (a[2].z - q) * (a[2].z - q) + 2.0 * off;
    const double p = std::sqrt(p2 / 6.0);
    // det((A - q I) / p) / 2, clamped against rounding.
    const double b00 = (a[0].x - q) / p, b11 = (a[1].y - q) / p, b22 = (a[2].z - q) / p;
    const double b01 = a[0].y / p, b02 = a[0].z / p, b12 = a[1].z / p;
    const double r = std::clamp(0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02)),
                                -1.0, 1.0);
    const double phi = std::acos(r) / 3.0;
    const double largest = q + 2.0 * p * std::cos(phi), smallest = q + 2.0 * p * std::cos(phi + 2.0 * M_PI / 3.0);
    return {smallest, largest};
}

}  // namespace

ViewProjection::ViewProjection(const Camera& camera, const Mat4& index_to_world) : camera_(camera) {
    if (!index_to_world.is_affine() || !index_to_world.inverse())
        throw GridError("the grid's index-to-world transform is singular or not affine");
    index_to_clip_ = camera.object_to_clip(index_to_world);
    const Vec3 w_gradient{index_to_clip_.m[3][0], index_to_clip_.m[3][1], index_to_clip_.m[3][2]};
    if (length(w_gradient) > 0) depth_axis_ = w_gradient / length(w_gradient);
    for (int r = 0; r < 3; ++r) metric_[r] = {dot(index_to_world.column(r), index_to_world.column(0)),
                                               dot(index_to_world.column(r), index_to_world.column(1)),
                                               dot(index_to_world.column(r), index_to_world.column(2))};
    const auto [smallest, largest] = metric_eigenvalue_range(metric_);
    const double k = largest / smallest;  // the angle between u and G u is at most atan((k - 1) / (2 sqrt k))
    max_line_scale_slope_ = k > 1 ? (k - 1) / (2 * std::sqrt(k)) : 0;
    // Rays go from camera space straight to index space: a grid and a camera far from the world's
    // origin never meet in world coordinates, where their offsets would cancel imprecisely.
    const Mat4 index_to_camera = camera.world_to_camera() * index_to_world;
    const auto camera_to_index = index_to_camera.inverse();
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
    // W^T (W d) = W^T wd: the world direction turned back by the transposed linear part.
    auto transposed_times = [&](const Vec3& w) {
        const Vec3 a = index_to_world.column(0), b = index_to_world.column(1), c = index_to_world.column(2);
        return Vec3{dot(a, w), dot(b, w), dot(c, w)};
    };
    gd0_ = transposed_times(wd0_);
    gdx_ = transposed_times(wdx_);
    gdy_ = transposed_times(wdy_);
    // Depth = -z in camera space: minus the third row of world_to_camera * index_to_world.
    depth_gradient_ = Vec3{-index_to_camera.m[2][0], -index_to_camera.m[2][1], -index_to_camera.m[2][2]};
    depth_offset_ = -index_to_camera.m[2][3];
}

ViewProjection::EyeOffset ViewProjection::eye_offset(const Vec3& index_pos) const {
    const Vec3 w = index_pos - eye_;
    const double depth = dot(depth_axis_, w), w2 = dot(w, w);
    // World length per index length along u is sqrt(u.G u); its relative change per radian is
    // tan(angle between u and G u).
    const Vec3 gw{dot(metric_[0], w), dot(metric_[1], w), dot(metric_[2], w)};
    const double along = dot(gw, w);
    const double across = std::sqrt(std::max(0.0, dot(gw, gw) * w2 - along * along));
    return {depth, std::sqrt(std::max(0.0, w2 - depth * depth)), along > 0 ? across / along : 0.0};
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
