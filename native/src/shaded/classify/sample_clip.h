/// @file sample_clip.h
/// @brief A grid's clip region at the shaded samples: the share of each sample's stretch of ray that is
/// kept, and the cut face's normal.
///
/// A sample stands for a stretch of its ray (a slab of a sheet, a ray caster's step): it counts for the
/// share of that stretch on the kept side of every plane, as a sample half in front of the camera's near
/// plane counts half (sheet_walk.h), so a cut is exact to within a sample's stretch and moves smoothly.
/// The density's gradient at a cut face is that of the uncut field, which inside bone or tissue is weak
/// and points anywhere: samples within `face_depth` (world, a voxel) of a plane, and samples behind it
/// whose gradient is no stronger than the kernels' ripple, are lit with the plane's normal instead, so a
/// cut face shows as a flat surface under the lights and the boundaries behind it keep their relief. The sheet walk (eight lanes)
/// and the ray caster (one sample) share these formulas: T is float8 or double.
#pragma once

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <vector>

#include "pcvr/clip_region.h"
#include "pcvr/lanes.h"

namespace pcvr {

class SampleClip {
public:
    /// `world`'s planes with unit normals, relative to `origin` (positions passed in are relative to it).
    SampleClip(const ClipRegion& world, const Vec3& origin, double face_depth) : face_depth_(face_depth) {
        for (const ClipPlane& p : world.planes()) {
            const double unit = 1.0 / length(p.normal);
            planes_.push_back({p.normal * unit, p.at(origin) * unit});
        }
    }

    /// The share of the stretch position - half_stretch to position + half_stretch that lies inside.
    template <class T, class V>
    T share(const V& position, const V& half_stretch) const {
        const T one = constant<T>(1.0), zero = constant<T>(0.0);
        T lo = -one, hi = one;
        for (const ClipPlane& p : planes_) {
            const T value = at<T>(p, position), rate = at<T>(p, half_stretch) - constant<T>(p.offset);
            // value + rate tau >= 0 for tau in [-1, 1]; a stretch along the plane is wholly in or out.
            const T bound = -value / rate;
            lo = pick(rate > zero, larger(lo, bound), lo);
            hi = pick(rate < zero, smaller(hi, bound), hi);
            hi = pick((rate == zero) & (value < zero), -one - one, hi);
        }
        const T kept = (smaller(hi, one) - larger(lo, -one)) * constant<T>(0.5);
        return larger(smaller(kept, one), zero);
    }

    /// The gradient a sample is lit by: the nearest plane's normal where the sample lies within face_depth
    /// of it, or where its own gradient is weak (a lane mask, see weak_gradient), `gradient` elsewhere.
    template <class T, class V, class Mask>
    V face_gradient(const V& position, const V& gradient, Mask weak) const {
        T nearest = constant<T>(INFINITY);
        V normal = gradient;
        for (const ClipPlane& p : planes_) {
            const T distance = at<T>(p, position);
            const auto closer = distance < nearest;
            nearest = pick(closer, distance, nearest);
            normal = {pick(closer, constant<T>(p.normal.x), normal.x), pick(closer, constant<T>(p.normal.y), normal.y),
                      pick(closer, constant<T>(p.normal.z), normal.z)};
        }
        const auto face = (nearest < constant<T>(face_depth_)) | weak;
        return {pick(face, normal.x, gradient.x), pick(face, normal.y, gradient.y), pick(face, normal.z, gradient.z)};
    }

    /// Where a gradient of `magnitude` (per world unit) is no stronger than the kernels' ripple in a flat
    /// region: the sum of Gaussians over the lattice is one to within 0.5%, a ripple a voxel long whose slope
    /// is about 3% of the density's departure from the background per voxel. Inside homogeneous tissue that
    /// ripple is all the gradient there is, and lit by it a cut face shows the lattice (a checkered pattern):
    /// below kWeakGradient (three times it) the plane's normal lights the sample instead.
    template <class T>
    auto weak_gradient(T magnitude, T departure) const {
        return magnitude * constant<T>(face_depth_) < constant<T>(kWeakGradient) * abs_of(departure);
    }
    static constexpr double kWeakGradient = 0.1;

    /// True (per lane) where the position itself lies inside.
    template <class T, class V>
    auto inside(const V& position) const {
        const T zero = constant<T>(0.0);
        auto kept = zero == zero;
        for (const ClipPlane& p : planes_) kept = kept & (at<T>(p, position) >= zero);
        return kept;
    }

private:
    template <class T>
    static T constant(double x) {
        if constexpr (std::is_same_v<T, double>)
            return x;
        else
            return broadcast8(float(x));
    }
    /// The plane's value at a position (relative to the origin).
    template <class T, class V>
    static T at(const ClipPlane& p, const V& v) {
        return v.x * constant<T>(p.normal.x) + v.y * constant<T>(p.normal.y) + v.z * constant<T>(p.normal.z) + constant<T>(p.offset);
    }
    // Lane-wise choices that read the same for one double and for eight floats.
    static double pick(bool c, double a, double b) { return c ? a : b; }
    static float8 pick(int8x c, float8 a, float8 b) { return select8(c, a, b); }
    static double larger(double a, double b) { return std::max(a, b); }
    static double abs_of(double a) { return std::abs(a); }
    static float8 abs_of(float8 a) { return abs8(a); }
    static float8 larger(float8 a, float8 b) { return max8(a, b); }
    static double smaller(double a, double b) { return std::min(a, b); }
    static float8 smaller(float8 a, float8 b) { return min8(a, b); }

    std::vector<ClipPlane> planes_;
    double face_depth_;
};

}  // namespace pcvr
