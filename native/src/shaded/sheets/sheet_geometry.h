/// @file sheet_geometry.h
/// @brief Where the sheets lie: every pixel's ray as an affine function of depth, and the frames of eight
/// pixels' samples on a sheet (planes of constant depth, or spheres around a perspective eye in the
/// sheet metric, SheetLattice).
#pragma once

#include <vector>

#include "pcvr/camera.h"
#include "pcvr/lanes.h"
#include "pcvr/math.h"

namespace pcvr {

/// World positions along pixel rays in terms of depth: point(px, py, z) = origin(px, py) + z dir(px, py),
/// both affine in pixel coordinates (every pinhole and orthographic camera).
struct SheetGeometry {
    Vec3 origin0, origin_dx, origin_dy;  ///< where a pixel's ray has depth 0 (the eye, in perspective)
    Vec3 dir0, dir_dx, dir_dy;           ///< world displacement per unit of depth along the ray
    double world_per_depth = 1;          ///< world length of a unit of depth along the view axis
    double longest_ray = 1;              ///< the largest |direction| over the image (its corners)
    /// Spheres (perspective): the directions in the sheet metric (metric * dir0, ...; the world's own
    /// unless use_metric) and bounds of |metric * direction| over the image: sheet parameter per unit
    /// of depth.
    Vec3 metric_dir0, metric_dir_dx, metric_dir_dy;
    double least_metric_ray = 1, longest_metric_ray = 1;
    /// Planes (orthographic): the sheet parameter where pixel (px, py)'s ray has depth 0 is
    /// plane_u0 + plane_ux px + plane_uy py, and it grows by 1 / plane_k per unit of depth (0, 0, 0
    /// and 1 for planes of constant depth).
    double plane_u0 = 0, plane_ux = 0, plane_uy = 0, plane_k = 1;
    /// Its least and most over the image's corners (an affine function of the pixel: its extremes).
    double plane_u0_least = 0, plane_u0_most = 0;

    explicit SheetGeometry(const Camera& camera);
    /// Sheets in this metric (the linear part of `metric`): spheres around a perspective eye, or
    /// sheet_planes for an orthographic camera; see SheetLattice.
    void use_metric(const Mat4& metric, const Camera& camera);
    Vec3 direction(double px, double py) const { return dir0 + dir_dx * px + dir_dy * py; }
    Vec3 point(double px, double py, double z) const { return origin0 + origin_dx * px + origin_dy * py + direction(px, py) * z; }
};

/// Eight pixels' samples on one sheet: world position relative to SheetGeometry::origin0, the world displacement per pixel right and
/// down on the sheet and per unit of the sheet parameter along the ray, and the sample's depth.
struct SampleFrames {
    Vec3x8 position, per_pixel_x, per_pixel_y, along;
    float8 depth;       ///< camera-space depth (the clip planes and the Depth pass use it)
    float8 depth_rate;  ///< camera-space depth per unit of the sheet parameter
};

/// The metric of spherical sheets for grids with these index-to-world transforms (of those with active
/// voxels): their common index metric, scaled to keep volumes, when all of them have voxels of one
/// shape up to rotation and scale (a CT's 1 x 1 x 2 voxels, its levels, a mask on the same lattice):
/// their kernels are round there, and each one's slab shares hold at every tap, as for cubic voxels
/// in world space. The world's own (identity) otherwise: cubic voxels, or voxel shapes that differ,
/// where anisotropic kernels take each tap's own share.
Mat4 sheet_metric(const std::vector<Mat4>& index_to_worlds);

/// True for the world's own metric (a linear part of exactly the identity).
bool is_identity(const Mat4& metric);

/// The metric length of one index unit when a grid's voxels are cubes in `metric` (its kernels
/// round), else 0.
double round_scale(const Mat4& metric, const Mat4& index_to_world);

/// Orthographic sheets: planes of u = dot(gradient, x) + offset (x in world space). Camera depth for
/// the world's own metric; otherwise perpendicular to the rays in `metric` (tilted in world space:
/// they cut voxels that are cubes there as the depth planes cut cubic voxels), u measured in it.
struct SheetPlanes {
    Vec3 gradient;
    double offset = 0;
};
SheetPlanes sheet_planes(const Camera& camera, const Mat4& metric);

/// Eight lanes of one vector.
inline Vec3x8 lanes3(const Vec3& v) { return {broadcast8(float(v.x)), broadcast8(float(v.y)), broadcast8(float(v.z))}; }

/// The frames of pixels (px, py) on the sheet at parameter u: planes of depth u, or spheres of
/// radius u around the eye in the sheet metric. Inline: the walk asks for them for every eight pixels
/// of every sheet.
__attribute__((always_inline)) inline SampleFrames sample_frames(const SheetGeometry& geo, bool spherical, float8 px, float py, double u) {
    const Vec3x8 dir = lanes3(geo.dir0 + geo.dir_dy * double(py)) + lanes3(geo.dir_dx) * px;
    // Relative to origin0 (the eye in perspective): float resolves positions near the camera.
    const Vec3x8 origin = lanes3(geo.origin_dy * double(py)) + lanes3(geo.origin_dx) * px;
    SampleFrames f;
    if (!spherical) {
        // The depth where the pixel's ray meets the plane u.
        const float k = float(geo.plane_k), ux = float(geo.plane_ux * geo.plane_k);
        const float8 depth = (float((u - geo.plane_u0 - geo.plane_uy * double(py)) * geo.plane_k)) - ux * px;
        f.position = origin + dir * depth;
        f.per_pixel_x = lanes3(geo.origin_dx) + lanes3(geo.dir_dx) * depth - dir * ux;
        f.per_pixel_y = lanes3(geo.origin_dy) + lanes3(geo.dir_dy) * depth - dir * float(geo.plane_uy * geo.plane_k);
        f.along = dir * k;
        f.depth = depth;
        f.depth_rate = broadcast8(k);
        return f;
    }
    // On the sphere of radius u around the eye: the point where the metric length of the way there is
    // u, u / |M dir| along dir; it moves per pixel by dir's change less its part along the ray that
    // keeps the metric length, over |M dir|.
    const Vec3x8 metric_dir = lanes3(geo.metric_dir0 + geo.metric_dir_dy * double(py)) + lanes3(geo.metric_dir_dx) * px;
    const float8 inverse_length = 1.0f / sqrt8(dot(metric_dir, metric_dir));
    const Vec3x8 d = dir * inverse_length, metric_d = metric_dir * inverse_length;
    auto turn = [&](const Vec3& change, const Vec3& metric_change) {
        return (lanes3(change) - d * dot(metric_d, lanes3(metric_change))) * (inverse_length * float(u));
    };
    f.position = origin + d * float(u);
    f.per_pixel_x = turn(geo.dir_dx, geo.metric_dir_dx);
    f.per_pixel_y = turn(geo.dir_dy, geo.metric_dir_dy);
    f.along = d;
    f.depth_rate = inverse_length;  // dir advances one unit of depth per |M dir| of the sheet parameter
    f.depth = inverse_length * float(u);
    return f;
}

}  // namespace pcvr
