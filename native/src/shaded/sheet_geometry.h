/// @file sheet_geometry.h
/// @brief Where the sheets lie: every pixel's ray as an affine function of depth, and the frames of eight
/// pixels' samples on a sheet (planes of constant depth, or spheres around a perspective eye).
#pragma once

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

    explicit SheetGeometry(const Camera& camera);
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

/// Eight lanes of one vector.
inline Vec3x8 lanes3(const Vec3& v) { return {broadcast8(float(v.x)), broadcast8(float(v.y)), broadcast8(float(v.z))}; }

/// The frames of pixels (px, py) on the sheet at parameter u: planes of depth u, or spheres of
/// world radius u around the eye. Inline: the walk asks for them for every eight pixels of every sheet.
inline SampleFrames sample_frames(const SheetGeometry& geo, bool spherical, float8 px, float py, double u) {
    const Vec3x8 dir = lanes3(geo.dir0 + geo.dir_dy * double(py)) + lanes3(geo.dir_dx) * px;
    // Relative to origin0 (the eye in perspective): float resolves positions near the camera.
    const Vec3x8 origin = lanes3(geo.origin_dy * double(py)) + lanes3(geo.origin_dx) * px;
    SampleFrames f;
    if (!spherical) {
        f.position = origin + dir * float(u);
        f.per_pixel_x = lanes3(geo.origin_dx + geo.dir_dx * u);
        f.per_pixel_y = lanes3(geo.origin_dy + geo.dir_dy * u);
        f.along = dir;
        f.depth = broadcast8(float(u));
        f.depth_rate = broadcast8(1.0f);
        return f;
    }
    // On the sphere of radius u around the eye: the point u along the unit direction d = dir / |dir|,
    // which turns per pixel by the part of dir's change across d, over |dir|.
    const float8 inverse_length = 1.0f / sqrt8(dot(dir, dir));
    const Vec3x8 d = dir * inverse_length;
    auto turn = [&](const Vec3& change) {
        const Vec3x8 c = lanes3(change);
        return (c - d * dot(d, c)) * (inverse_length * float(u));
    };
    f.position = origin + d * float(u);
    f.per_pixel_x = turn(geo.dir_dx);
    f.per_pixel_y = turn(geo.dir_dy);
    f.along = d;
    f.depth_rate = inverse_length;  // dir advances one unit of depth per |dir| of world length
    f.depth = inverse_length * float(u);
    return f;
}

}  // namespace pcvr
