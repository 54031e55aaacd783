#include "pcvr/camera.h"

#include <algorithm>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

Vec3 unproject(const Mat4& clip_to_world, double x, double y, double z) {
    const Vec4 h = clip_to_world * Vec4{x, y, z, 1.0};
    return Vec3{h.x, h.y, h.z} / h.w;
}

double max_abs(const Vec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

}  // namespace

Camera::Camera(const Mat4& world_to_camera, const Mat4& projection, int width, int height)
    : world_to_camera_(world_to_camera), projection_(projection), width_(width), height_(height) {
    constexpr int kMaxSide = 1 << 16;
    if (width <= 0 || height <= 0 || width > kMaxSide || height > kMaxSide)
        throw CameraError("invalid camera: image size " + std::to_string(width) + " x " + std::to_string(height) +
                          " (each side must be 1 to " + std::to_string(kMaxSide) + " pixels)");
    if (!world_to_camera.is_finite()) throw CameraError("invalid camera: world_to_camera contains a non-finite value");
    if (!projection.is_finite()) throw CameraError("invalid camera: projection contains a non-finite value");
    const auto camera_to_world = world_to_camera.inverse();
    if (!camera_to_world) throw CameraError("invalid camera: world_to_camera is singular");
    if (!world_to_camera.is_affine())
        throw CameraError("invalid camera: world_to_camera is not affine (its last row must be 0 0 0 1)");
    const auto clip_to_camera = projection.inverse();
    if (!clip_to_camera) throw CameraError("invalid camera: projection is singular");
    camera_to_world_ = *camera_to_world;
    clip_to_camera_ = *clip_to_camera;
    world_to_clip_ = projection * world_to_camera;
    clip_to_world_ = camera_to_world_ * clip_to_camera_;
    const auto& p = projection.m[3];
    orthographic_ = p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0 && p[3] != 0.0;
    // The centre of projection maps to clip (0, 0, z, 0): x = y = w = 0.
    const Vec4 centre = clip_to_camera_ * Vec4{0.0, 0.0, 1.0, 0.0};
    if (!orthographic_ && centre.w != 0.0) eye_ = Vec3{centre.x, centre.y, centre.z} / centre.w;

    ray0_ = camera_ray(0, 0);
    const Ray rx = camera_ray(1, 0), ry = camera_ray(0, 1);
    ray_dx_ = {rx.origin - ray0_.origin, rx.direction - ray0_.direction};
    ray_dy_ = {ry.origin - ray0_.origin, ry.direction - ray0_.direction};

    // The splatting path relies on rays varying affinely across the image (true of every pinhole and
    // orthographic camera, shifted or not). Check it at the far corner instead of assuming it.
    const double fx = width - 1, fy = height - 1;
    const Ray far = camera_ray(fx, fy);
    const Vec3 o_err = far.origin - (ray0_.origin + ray_dx_.origin * fx + ray_dy_.origin * fy);
    const Vec3 d_err = far.direction - (ray0_.direction + ray_dx_.direction * fx + ray_dy_.direction * fy);
    const double o_scale = max_abs(far.origin) + max_abs(ray0_.origin) + max_abs(far.direction);
    const double d_scale = max_abs(far.direction) + max_abs(ray0_.direction);
    if (!(max_abs(o_err) <= 1e-6 * o_scale) || !(max_abs(d_err) <= 1e-6 * d_scale) || !(length(far.direction) > 0))
        throw CameraError("invalid camera: the projection is neither perspective nor orthographic "
                          "(pixel rays do not vary linearly across the image)");
}

Ray Camera::camera_ray(double px, double py) const {
    // Unprojected in camera space: the direction never passes through world coordinates, whose
    // magnitude (a camera 1e8 units out) would swamp a short clip range.
    const double x = ndc_x(px), y = ndc_y(py);
    const Vec3 near = unproject(clip_to_camera_, x, y, -1.0);
    const Vec3 far = unproject(clip_to_camera_, x, y, 1.0);
    return {near, far - near};
}

Ray Camera::pixel_ray(double px, double py) const {
    const Ray r = camera_ray(px, py);
    return {camera_to_world_.transform_point(r.origin), camera_to_world_.transform_vector(r.direction)};
}

}  // namespace pcvr
