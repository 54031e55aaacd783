/// @file camera.h
/// @brief A pinhole or orthographic camera given by Blender's matrices, and its pixel rays.
///
/// `world_to_camera` maps world space to camera space (looking down -Z); `projection` maps camera
/// space to OpenGL clip space, exactly what bpy's `Object.calc_matrix_camera` returns, so shift,
/// sensor fit and pixel aspect need no parameters of their own. Pixel (c, r) has its centre at
/// NDC x = (c + 0.5) / width * 2 - 1, y = 1 - (r + 0.5) / height * 2: row 0 is the top row.
/// "Pixel coordinates" below are continuous: pixel (c, r) has its centre at (c, r).
#pragma once

#include "pcvr/math.h"

namespace pcvr {

/// A ray o + t d with d not normalised: t = 0 on the near plane, t = 1 on the far plane.
struct Ray {
    Vec3 origin;
    Vec3 direction;
};

class Camera {
public:
    /// Throws CameraError when a matrix is singular or not finite, the image is empty or huge,
    /// or the projection is neither a pinhole nor an orthographic one (its rays must vary affinely
    /// across the image).
    Camera(const Mat4& world_to_camera, const Mat4& projection, int width, int height);

    int width() const { return width_; }
    int height() const { return height_; }
    bool orthographic() const { return orthographic_; }
    const Mat4& world_to_camera() const { return world_to_camera_; }
    const Mat4& projection() const { return projection_; }
    const Mat4& world_to_clip() const { return world_to_clip_; }
    const Mat4& clip_to_world() const { return clip_to_world_; }
    /// projection * world_to_camera * object_to_world, composed from the right: a volume and a camera
    /// both far from the origin (1e8 units) meet in camera space, where their offsets cancel before
    /// the projection scales them.
    Mat4 object_to_clip(const Mat4& object_to_world) const { return projection_ * (world_to_camera_ * object_to_world); }

    /// T: double, or a vector of doubles (several points at once).
    template <class T>
    T pixel_x(T ndc_x) const { return (ndc_x + 1.0) * 0.5 * double(width_) - 0.5; }
    template <class T>
    T pixel_y(T ndc_y) const { return (1.0 - ndc_y) * 0.5 * double(height_) - 0.5; }
    double ndc_x(double px) const { return (px + 0.5) / width_ * 2.0 - 1.0; }
    double ndc_y(double py) const { return 1.0 - (py + 0.5) / height_ * 2.0; }

    /// The ray through pixel coordinates (px, py), from the near to the far plane, in camera space.
    Ray camera_ray(double px, double py) const;
    /// The same ray in world space.
    Ray pixel_ray(double px, double py) const;
    const Mat4& camera_to_world() const { return camera_to_world_; }
    /// Where every ray of a perspective camera passes, in camera space (the origin for Blender's
    /// cameras, shifted or not); meaningless for orthographic ones.
    const Vec3& eye() const { return eye_; }

    /// Rays are affine in pixel coordinates: ray(px, py) = ray(0, 0) + px * d/dpx + py * d/dpy
    /// (camera space; an object's own space is one affine map away, see ViewProjection).
    const Ray& ray_at_origin() const { return ray0_; }
    const Ray& ray_per_pixel_x() const { return ray_dx_; }
    const Ray& ray_per_pixel_y() const { return ray_dy_; }

private:
    Mat4 world_to_camera_, projection_, world_to_clip_, clip_to_world_;
    Mat4 camera_to_world_, clip_to_camera_;
    Vec3 eye_;
    int width_, height_;
    bool orthographic_;
    Ray ray0_, ray_dx_, ray_dy_;
};

}  // namespace pcvr
