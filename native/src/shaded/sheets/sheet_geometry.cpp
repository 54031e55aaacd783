#include "shaded/sheets/sheet_geometry.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

namespace pcvr {

namespace {

/// The upper-left 3 x 3 of a^T a, and how far it is from c^2 times the identity (relative).
double gram_scale(const Mat4& a, double& c) {
    double g[3][3] = {};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) g[i][j] += a.m[k][i] * a.m[k][j];
    const double c2 = (g[0][0] + g[1][1] + g[2][2]) / 3.0;
    double off = 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) off = std::max(off, std::abs(g[i][j] - (i == j ? c2 : 0.0)));
    c = std::sqrt(c2);
    return c2 > 0 ? off / c2 : INFINITY;
}

/// Voxels whose shape differs by less than this (relative, in the Gram matrix) count as one shape:
/// the slab shares then move by at most ~1e-6 of a voxel across a footprint.
constexpr double kSameShape = 1e-6;

}  // namespace

bool is_identity(const Mat4& metric) {
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (metric.m[i][j] != (i == j ? 1.0 : 0.0)) return false;
    return true;
}

double round_scale(const Mat4& metric, const Mat4& index_to_world) {
    double c = 0;
    return gram_scale(metric * index_to_world, c) <= kSameShape ? c : 0.0;
}

Mat4 sheet_metric(const std::vector<Mat4>& index_to_worlds) {
    std::optional<Mat4> metric;
    for (const Mat4& index_to_world : index_to_worlds) {
        const std::optional<Mat4> inverse = index_to_world.inverse();
        if (!inverse) return Mat4();
        Mat4 m = *inverse;
        m.m[0][3] = m.m[1][3] = m.m[2][3] = 0;
        // Scaled to keep volumes: the world's own metric for cubic voxels.
        const double det = m.m[0][0] * (m.m[1][1] * m.m[2][2] - m.m[1][2] * m.m[2][1]) -
                           m.m[0][1] * (m.m[1][0] * m.m[2][2] - m.m[1][2] * m.m[2][0]) +
                           m.m[0][2] * (m.m[1][0] * m.m[2][1] - m.m[1][1] * m.m[2][0]);
        const double scale = 1.0 / std::cbrt(std::abs(det));
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) m.m[i][j] *= scale;
        if (!metric) metric = m;
        else if (round_scale(*metric, index_to_world) == 0) return Mat4();  // shapes differ: world spheres
    }
    // Voxels that are cubes in world space keep the world's metric exactly (the scaled inverse of
    // 0.1 x the identity is the identity only to rounding).
    bool cubes = true;
    for (const Mat4& index_to_world : index_to_worlds) cubes = cubes && round_scale(Mat4(), index_to_world) > 0;
    return metric && !cubes ? *metric : Mat4();
}


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
    use_metric(Mat4(), camera);
}

SheetPlanes sheet_planes(const Camera& camera, const Mat4& metric) {
    const Mat4& w2c = camera.world_to_camera();
    const Vec3 depth_gradient{-w2c.m[2][0], -w2c.m[2][1], -w2c.m[2][2]};
    if (is_identity(metric)) return {depth_gradient, -w2c.m[2][3]};
    // u = (M d) . (M x) / |M d|, d the rays' direction, zero on the plane through the camera.
    const Vec3 d = depth_gradient / length(depth_gradient);
    const Vec3 md = metric.transform_vector(d);
    const Vec3 gradient = Vec3{dot(metric.column(0), md), dot(metric.column(1), md), dot(metric.column(2), md)} / length(md);
    const Vec3 camera_at = w2c.inverse()->transform_point({0, 0, 0});
    return {gradient, -dot(gradient, camera_at)};
}

void SheetGeometry::use_metric(const Mat4& metric, const Camera& camera) {
    const int width = camera.width(), height = camera.height();
    metric_dir0 = metric.transform_vector(dir0);
    metric_dir_dx = metric.transform_vector(dir_dx);
    metric_dir_dy = metric.transform_vector(dir_dy);
    longest_metric_ray = 0;
    for (double px : {0.0, double(width - 1)})
        for (double py : {0.0, double(height - 1)})
            longest_metric_ray = std::max(longest_metric_ray, length(metric_dir0 + metric_dir_dx * px + metric_dir_dy * py));
    // |M dir| >= |dir| / |M^-1|, and the shortest direction is the axis's.
    const std::optional<Mat4> inverse = metric.inverse();
    least_metric_ray = inverse ? world_per_depth / largest_singular_value(*inverse) : 0.0;
    if (camera.orthographic()) {
        const SheetPlanes planes = sheet_planes(camera, metric);
        plane_u0 = dot(planes.gradient, origin0) + planes.offset;
        plane_ux = dot(planes.gradient, origin_dx);
        plane_uy = dot(planes.gradient, origin_dy);
        plane_k = 1.0 / dot(planes.gradient, dir0);
        plane_u0_least = INFINITY, plane_u0_most = -INFINITY;
        for (double px : {0.0, double(width - 1)})
            for (double py : {0.0, double(height - 1)}) {
                const double at_zero = plane_u0 + plane_ux * px + plane_uy * py;
                plane_u0_least = std::min(plane_u0_least, at_zero), plane_u0_most = std::max(plane_u0_most, at_zero);
            }
    }
}

}  // namespace pcvr
