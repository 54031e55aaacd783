/// @file view_projection.h
/// @brief Where one grid's voxels land on the image: projected centre, elliptical footprint, ray scale.
///
/// A voxel's kernel is spherical in index space. The rays near its projected centre p cross the plane
/// through the voxel perpendicular to the central ray at points y(p + delta) ~ c + U dx + V dy, so the
/// distance of a ray from the centre is rho^2 = |U dx + V dy|^2 = qxx dx^2 + 2 qxy dx dy + qyy dy^2:
/// the footprint is an ellipse. Orthographic: the form is the same for every voxel. Perspective: it is
/// evaluated per voxel (the linearisation is exact at the centre and first-order accurate across the
/// footprint, whose size is tiny compared with the distance to the eye).
///
/// Depth is the distance in front of the eye plane along the view axis, in camera-space units
/// (-z in camera space). It is affine in index space, so sheets of constant depth (the shaded
/// renderer's) cut every voxel's kernel the same way up to its position: the footprint also carries
/// how the depth of each ray's closest approach to the centre changes across it, which is what turns
/// a sheet's depth range into a range along each ray (src/shaded/sheets/slab_splat.h).
#pragma once

#include "pcvr/camera.h"
#include "pcvr/math.h"

namespace pcvr {

/// The footprint arithmetic's inputs and outputs for one voxel (T = double) or several at once
/// (T = a GCC vector of doubles), so that the scalar and the batched splats share one formula.
template <class T>
struct FootprintLanes {
    T px, py;            ///< projected centre, pixel coordinates
    T qxx, qxy, qyy;     ///< see Footprint
    T line_scale;
    T depth;             ///< depth of the centre
    T depth_dx, depth_dy;  ///< change per pixel offset of the depth where each ray passes closest to the centre
    T depth_per_index;   ///< depth per index length along the ray (> 0)
    T distance_dx, distance_dy;  ///< the same for the world distance along the ray (spherical sheets)
};

struct Footprint {
    double px = 0, py = 0;              ///< projected centre, pixel coordinates
    double qxx = 0, qxy = 0, qyy = 0;   ///< rho^2 in index units^2 per pixel offset, see above
    double line_scale = 1;              ///< world length per index length along the ray
    double depth = 0, depth_dx = 0, depth_dy = 0, depth_per_index = 1;  ///< see FootprintLanes
    double distance_dx = 0, distance_dy = 0;                            ///< see FootprintLanes

    /// Smallest number of pixels that one index unit spans in any direction (the magnification that
    /// limits the subgrid stride).
    double min_pixels_per_voxel() const;
    /// Half-widths in pixels of the bounding box of the ellipse rho <= radius.
    double extent_x(double radius) const;
    double extent_y(double radius) const;
    /// Integral of the footprint over the image plane in pixel^2, for a unit-integral kernel.
    double area_integral() const;
};

class ViewProjection {
public:
    /// Throws GridError when the index-to-world transform is singular or not affine.
    ViewProjection(const Camera& camera, const Mat4& index_to_world);

    const Camera& camera() const { return camera_; }
    bool orthographic() const { return camera_.orthographic(); }
    const Mat4& index_to_clip() const { return index_to_clip_; }

    /// True when a point's centre lies between the clip planes (its voxel contributes in full).
    static bool inside_clip_range(const Vec4& clip) { return clip.w > 0 && clip.z >= -clip.w && clip.z <= clip.w; }
    Vec4 to_clip(const Vec3& index_pos) const { return index_to_clip_ * Vec4{index_pos.x, index_pos.y, index_pos.z, 1.0}; }

    /// Depth (see above) of a point in index space, and its gradient: depth = dot(gradient, p) + offset.
    double depth(const Vec3& index_pos) const { return dot(depth_gradient_, index_pos) + depth_offset_; }
    const Vec3& depth_gradient() const { return depth_gradient_; }

    /// The ray through pixel coordinates (px, py) in index space (from the near to the far plane),
    /// and the same ray's direction in world space.
    Ray index_ray(double px, double py) const { return {o0_ + ox_ * px + oy_ * py, d0_ + dx_ * px + dy_ * py}; }
    Vec3 world_direction(double px, double py) const { return wd0_ + wdx_ * px + wdy_ * py; }
    /// A perspective camera's eye in index space (meaningless for orthographic views).
    const Vec3& eye() const { return eye_; }
    /// Perspective views: where a point lies relative to the eye, in index units. `depth` is its
    /// distance from the plane through the eye parallel to the image (negative behind it),
    /// `lateral` its distance from the line through the eye perpendicular to that plane, and
    /// `line_scale_slope` how fast the world length per index length of rays changes with their
    /// direction there (relative change per radian: 0 for cubic voxels, up to 2.6 for 1 x 1 x 2.5).
    struct EyeOffset {
        double depth, lateral, line_scale_slope;
    };
    EyeOffset eye_offset(const Vec3& index_pos) const;
    /// The largest line_scale_slope of any direction: (k - 1) / (2 sqrt(k)), k the condition number
    /// of the index-to-world metric.
    double max_line_scale_slope() const { return max_line_scale_slope_; }

    /// The footprint of the voxel at `index_pos`; false when it is outside the clip range.
    bool footprint(const Vec3& index_pos, Footprint& out) const;
    /// The same, ignoring the near and far planes; false only behind the eye.
    bool footprint_unclipped(const Vec3& index_pos, Footprint& out) const;

    /// The footprint of the voxel(s) at index position (x, y, z) whose clip coordinates are
    /// (clip_x, clip_y, ., clip_w), clip_w > 0. `sqrt` takes and returns a T.
    template <class T, class Sqrt>
    FootprintLanes<T> footprint_lanes(T x, T y, T z, T clip_x, T clip_y, T clip_w, Sqrt sqrt) const;

private:
    void footprint_at(const Vec3& c, const Vec4& clip, Footprint& out) const;

    Camera camera_;
    Mat4 index_to_clip_;
    // Pixel rays in index space (affine in pixel coordinates) and their world-space directions.
    Vec3 o0_, ox_, oy_, d0_, dx_, dy_;
    Vec3 wd0_, wdx_, wdy_;
    Vec3 gd0_, gdx_, gdy_;  // the index-space metric times d: (W d) . (W u) = (W^T W d) . u
    Vec3 depth_gradient_;
    double depth_offset_ = 0;

    Vec3 eye_;
    Vec3 depth_axis_;  // unit gradient of clip w in index space
    Vec3 metric_[3];   // rows of L^T L, L the linear part of index_to_world: world length^2 per index direction
    double max_line_scale_slope_ = 0;
};

template <class T, class Sqrt>
FootprintLanes<T> ViewProjection::footprint_lanes(T x, T y, T z, T clip_x, T clip_y, T clip_w, Sqrt sqrt) const {
    struct V {  // three lanes of T, with what the formula needs
        T x, y, z;
        V operator+(const V& o) const { return {x + o.x, y + o.y, z + o.z}; }
        V operator-(const V& o) const { return {x - o.x, y - o.y, z - o.z}; }
        V operator*(T s) const { return {x * s, y * s, z * s}; }
        T dot(const V& o) const { return x * o.x + y * o.y + z * o.z; }
    };
    auto lanes = [](const Vec3& v) { return V{T{} + v.x, T{} + v.y, T{} + v.z}; };
    FootprintLanes<T> out;
    out.px = camera_.pixel_x(clip_x / clip_w);
    out.py = camera_.pixel_y(clip_y / clip_w);

    // The ray through the centre's pixel, in index space: origin o, direction d (passes through c).
    const V o = lanes(o0_) + lanes(ox_) * out.px + lanes(oy_) * out.py;
    const V d = lanes(d0_) + lanes(dx_) * out.px + lanes(dy_) * out.py;
    const T dd = d.dot(d);
    const T t = (V{x, y, z} - o).dot(d) / dd;
    // Crossing points of neighbouring rays with the plane through c perpendicular to d move by
    // U per pixel in x and V per pixel in y (derivative of o + t d, projected onto the plane).
    V u = lanes(ox_) + lanes(dx_) * t, v = lanes(oy_) + lanes(dy_) * t;
    u = u - d * (u.dot(d) / dd);
    v = v - d * (v.dot(d) / dd);
    out.qxx = u.dot(u);
    out.qxy = u.dot(v);
    out.qyy = v.dot(v);

    // Depth: the closest approach of a neighbouring ray is (to first order) its crossing with that plane.
    const V n = lanes(depth_gradient_);
    out.depth = n.dot(V{x, y, z}) + depth_offset_;
    out.depth_dx = n.dot(u);
    out.depth_dy = n.dot(v);
    out.depth_per_index = n.dot(d) / sqrt(dd);

    const V wd = lanes(wd0_) + lanes(wdx_) * out.px + lanes(wdy_) * out.py;
    const T world_length = sqrt(wd.dot(wd));
    out.line_scale = world_length / sqrt(dd);
    // World distance along the ray: the closest approach moves along it by the part of W u along W d
    // (zero when voxels are cubes; anisotropic kernels are cut at an angle).
    const V gd = lanes(gd0_) + lanes(gdx_) * out.px + lanes(gdy_) * out.py;
    out.distance_dx = gd.dot(u) / world_length;
    out.distance_dy = gd.dot(v) / world_length;
    return out;
}

}  // namespace pcvr
