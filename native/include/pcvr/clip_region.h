/// @file clip_region.h
/// @brief The part of space a volume is kept in: clip planes and a crop box, cut exactly in the
/// reconstructed field.
///
/// A plane (a, b, c, d) keeps a x + b y + c z + d >= 0; a crop box is a world-to-box matrix M and
/// keeps the points whose box coordinates M p lie in [-1, 1]^3 (Blender's default cube, so an
/// object's inverted world matrix crops to that object), which is six planes. The region kept is the
/// intersection of them all: convex, so every ray crosses it in one interval. Renderers cut the
/// reconstructed field, not the voxels: a voxel whose kernel reaches across a plane contributes the
/// part of its kernel on the kept side (X-ray integrates the kept interval of each ray; shaded and MIP
/// samples count for the share of their stretch of ray inside).
/// A region in index space (ClipRegion::in_index_space) has planes normalised so that each plane's
/// value at a point is its signed distance in index units: kernels are spheres there.
#pragma once

#include <vector>

#include "pcvr/math.h"

namespace pcvr {

/// Keeps dot(normal, p) + offset >= 0.
struct ClipPlane {
    Vec3 normal;
    double offset = 0;

    double at(const Vec3& p) const { return dot(normal, p) + offset; }
};

/// Where a sphere (or a box) lies relative to a region.
enum class ClipSide { Inside, Outside, Straddles };

/// A parameter interval along a ray; empty when lo > hi.
struct RayInterval {
    double lo, hi;
    bool empty() const { return !(lo <= hi); }
};

class ClipRegion {
public:
    /// Everything kept.
    ClipRegion() = default;
    /// Throws InvalidArgument naming the plane or the box: a zero or non-finite normal, a non-finite
    /// offset, a box matrix that is not finite, not affine, or singular (an empty box).
    static ClipRegion from(const std::vector<ClipPlane>& planes, const Mat4* world_to_box = nullptr);

    bool keeps_everything() const { return planes_.empty(); }
    const std::vector<ClipPlane>& planes() const { return planes_; }

    /// The same region in the index space of a grid with this index-to-world transform, each plane's
    /// value a signed distance in index units.
    ClipRegion in_index_space(const Mat4& index_to_world) const;

    /// The kept stretch of the ray origin + t direction, t in [lo, hi] (any direction length).
    RayInterval ray_interval(const Vec3& origin, const Vec3& direction, double lo, double hi) const;

    /// Where a sphere of this radius lies, for a region in index space: Outside when some plane has
    /// it wholly on its far side (a sphere beyond the box's corner but inside every plane's half-space
    /// counts as straddling: exact, only slower).
    ClipSide sphere_side(const Vec3& centre, double radius) const;
    /// The same for the box [lo, hi] grown by `radius` on every side (a block of voxels' kernels).
    ClipSide box_side(const Vec3& lo, const Vec3& hi, double radius) const;

private:
    std::vector<ClipPlane> planes_;
};

}  // namespace pcvr
