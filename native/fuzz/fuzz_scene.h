/// @file fuzz_scene.h
/// @brief What the fuzz targets share: small renders with bounded time and memory, and random scenes
/// (a small volume, its transform and a camera) drawn from the fuzzer's bytes.
#pragma once

#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "pcvr/camera.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/render_control.h"
#include "pcvr/xray.h"

namespace pcvr::fuzz {

/// Renders of more voxels than this take too long for a fuzzing iteration.
constexpr uint64_t kMaxRenderedVoxels = 20000;
/// Every render's buffers must fit this (MemoryBudget refuses the rest up front).
constexpr uint64_t kMemoryLimit = uint64_t(256) << 20;

inline XrayImage render(const Grid& grid, const Camera& camera, XrayParams params) {
    params.threads = 1;
    params.memory_limit = kMemoryLimit;
    RenderControl control;
    return render_xray({{&grid, 1.0}}, camera, params, control);
}

/// An orthographic 16 x 16 view down -Z of the grid's active bounding box, by every method.
inline void render_framed(const Grid& grid) {
    const auto b = grid.index_bbox();
    const Mat4& m = grid.index_to_world();
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p = m.transform_point({double(b[(corner & 1) ? 3 : 0]), double(b[(corner & 2) ? 4 : 1]),
                                          double(b[(corner & 4) ? 5 : 2])});
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    }
    const double half = 0.5 * std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30}) * 1.5;
    Mat4 view;
    view.m[0][3] = -0.5 * (lo[0] + hi[0]);
    view.m[1][3] = -0.5 * (lo[1] + hi[1]);
    view.m[2][3] = -(hi[2] + half);
    Mat4 ortho;
    ortho.m[0][0] = ortho.m[1][1] = 1.0 / half;
    ortho.m[2][2] = -1.0 / (2.0 * half);
    ortho.m[2][3] = -1.0;
    try {
        const Camera camera(view, ortho, 16, 16);
        for (XrayMethod method : {XrayMethod::Exact, XrayMethod::Regular, XrayMethod::Pcvr, XrayMethod::BilinearSpread}) {
            XrayParams params;
            params.method = method;
            render(grid, camera, params);
        }
    } catch (const CameraError&) {
        // A box too large or too far out for a camera: nothing to render.
    }
}

inline Mat4 rotation(Vec3 axis, double angle) {
    const double n = length(axis);
    axis = n > 0 ? axis / n : Vec3{0, 0, 1};
    const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    Mat4 r;
    const double x = axis.x, y = axis.y, z = axis.z;
    r.m[0][0] = t * x * x + c, r.m[0][1] = t * x * y - s * z, r.m[0][2] = t * x * z + s * y;
    r.m[1][0] = t * x * y + s * z, r.m[1][1] = t * y * y + c, r.m[1][2] = t * y * z - s * x;
    r.m[2][0] = t * x * z - s * y, r.m[2][1] = t * y * z + s * x, r.m[2][2] = t * z * z + c;
    return r;
}

inline Vec3 consume_vec(FuzzedDataProvider& in, double range) {
    return {in.ConsumeFloatingPointInRange(-range, range), in.ConsumeFloatingPointInRange(-range, range),
            in.ConsumeFloatingPointInRange(-range, range)};
}

inline Mat4 consume_raw_matrix(FuzzedDataProvider& in) {
    Mat4 m;
    for (auto& row : m.m)
        for (double& v : row) v = in.ConsumeFloatingPoint<double>();
    return m;
}

/// world_to_camera for an eye looking at `target` (camera looks down -Z).
inline Mat4 look_at(const Vec3& eye, const Vec3& target, Vec3 up) {
    Vec3 f = target - eye;
    if (!(length(f) > 0)) f = {0, 0, -1};
    f = f / length(f);
    if (std::abs(dot(f, up / std::max(length(up), 1e-300))) > 0.99 || !(length(up) > 0))
        up = std::abs(f.y) < 0.9 ? Vec3{0, 1, 0} : Vec3{1, 0, 0};
    Vec3 x = cross(f, up);
    x = x / length(x);
    const Vec3 y = cross(x, f);
    Mat4 m;
    const Vec3 rows[3] = {x, y, -f};
    for (int r = 0; r < 3; ++r) {
        m.m[r][0] = rows[r].x, m.m[r][1] = rows[r].y, m.m[r][2] = rows[r].z;
        m.m[r][3] = -dot(rows[r], eye);
    }
    return m;
}

inline void print_matrix(const char* name, const Mat4& m) {
    std::fprintf(stderr, "%s = [", name);
    for (int r = 0; r < 4; ++r)
        std::fprintf(stderr, "[%.17g, %.17g, %.17g, %.17g]%s", m.m[r][0], m.m[r][1], m.m[r][2], m.m[r][3], r < 3 ? ", " : "]\n");
}

/// A small volume, its index-to-world transform and a camera, from the fuzzer's bytes: in a unit-scale
/// frame, then scaled by 1e-9 to 1e9 and moved up to 1e8 units out; now and then a matrix is raw doubles.
struct Scene {
    std::array<size_t, 3> shape{};
    std::vector<float> values;  ///< [i][j][k], C order (Grid::from_dense)
    float magnitude = 1;        ///< the values are in [-2, 2] times this
    Mat4 index_to_world, world_to_camera, projection;
    int width = 1, height = 1;
    bool perspective = false;
    double scale = 1;        ///< of the whole scene: world units per unit of the frame it was drawn in
    Vec3 eye_world;          ///< the camera's position (orthographic: the centre of its near plane's origin)
    bool well_posed = true;  ///< no raw matrix

    Grid grid() const { return Grid::from_dense(values.data(), shape, index_to_world, 0.0f); }  // GridError
    Camera camera() const { return Camera(world_to_camera, projection, width, height); }     // CameraError

    /// As Python, to turn a finding into a test.
    void print() const {
        std::fprintf(stderr, "shape = (%zu, %zu, %zu)\nvalues = [", shape[0], shape[1], shape[2]);
        for (float v : values) std::fprintf(stderr, "%.9g, ", v);
        std::fprintf(stderr, "]\n");
        print_matrix("index_to_world", index_to_world);
        print_matrix("world_to_camera", world_to_camera);
        print_matrix("projection", projection);
        std::fprintf(stderr, "width, height = %d, %d\n", width, height);
    }
};

/// The volume: up to 6^3 voxels, values in [-2, 2] times a power of ten from 1e-44 to 1e30, about half
/// zero. The transform: rotation x anisotropic scale x shear x mirror, centred. The camera: orthographic
/// or perspective, inside the volume or up to 40 units out, clip ranges up to 12 orders of magnitude,
/// images up to 40 x 40 and now and then 65536 on a side.
inline Scene consume_scene(FuzzedDataProvider& in) {
    Scene scene;
    const size_t nx = in.ConsumeIntegralInRange<size_t>(1, 6), ny = in.ConsumeIntegralInRange<size_t>(1, 6),
                 nz = in.ConsumeIntegralInRange<size_t>(1, 6);
    scene.shape = {nx, ny, nz};
    scene.magnitude = float(std::pow(10.0, in.ConsumeIntegralInRange<int>(-44, 30)));
    const bool signed_values = in.ConsumeBool();
    scene.values.resize(nx * ny * nz);
    for (float& v : scene.values) {
        const uint8_t byte = in.ConsumeIntegral<uint8_t>();
        v = byte < 128 ? 0.0f : scene.magnitude * float(byte - 127) / 64.0f * (signed_values && (byte & 1) ? -1.0f : 1.0f);
    }

    Mat4 linear = rotation(consume_vec(in, 1.0), in.ConsumeFloatingPointInRange(0.0, 7.0));
    Mat4 shape;
    for (int a = 0; a < 3; ++a) shape.m[a][a] = in.ConsumeFloatingPointInRange(0.2, 5.0) * (a == 0 && in.ConsumeBool() ? -1 : 1);
    shape.m[0][1] = in.ConsumeFloatingPointInRange(-0.6, 0.6);
    shape.m[1][2] = in.ConsumeFloatingPointInRange(-0.6, 0.6);
    Mat4 index_to_world = linear * shape;
    const Vec3 centre = index_to_world.transform_vector({(nx - 1) / 2.0, (ny - 1) / 2.0, (nz - 1) / 2.0});
    for (int r = 0; r < 3; ++r) index_to_world.m[r][3] = -centre[r];

    scene.perspective = in.ConsumeBool();
    const Vec3 eye = in.ConsumeBool() ? consume_vec(in, 2.0) : consume_vec(in, 40.0);
    const Mat4 view = look_at(eye, consume_vec(in, 3.0), consume_vec(in, 1.0));
    const double near = std::pow(10.0, in.ConsumeFloatingPointInRange(-4.0, 1.0));
    const double far = near * std::pow(10.0, in.ConsumeFloatingPointInRange(0.5, 12.0));
    const double half = in.ConsumeFloatingPointInRange(0.05, 40.0);  // orthographic half width, or tan(fov / 2)
    int& width = scene.width;
    int& height = scene.height;
    width = in.ConsumeIntegralInRange<int>(1, 40), height = in.ConsumeIntegralInRange<int>(1, 40);
    if (in.ConsumeIntegralInRange<int>(0, 15) == 0) (in.ConsumeBool() ? width : height) = in.ConsumeIntegralInRange<int>(1, 1 << 16);

    // Scale and offset of the whole scene.
    const double scale = scene.scale = std::pow(10.0, in.ConsumeFloatingPointInRange(-9.0, 9.0));
    const Vec3 offset = scale >= 1e-2 && in.ConsumeBool() ? consume_vec(in, 1e8) : Vec3{};
    Mat4 scaling;
    scaling.m[0][0] = scaling.m[1][1] = scaling.m[2][2] = scale;
    scaling.m[0][3] = offset.x, scaling.m[1][3] = offset.y, scaling.m[2][3] = offset.z;
    scene.index_to_world = scaling * index_to_world;
    // The view's rotation from the unit-scale frame (1e8 out, target - eye would round), its
    // translation from where the eye now is.
    scene.world_to_camera = view;
    scene.eye_world = eye * scale + offset;
    for (int r = 0; r < 3; ++r)
        scene.world_to_camera.m[r][3] = -dot(Vec3{view.m[r][0], view.m[r][1], view.m[r][2]}, scene.eye_world);
    Mat4& projection = scene.projection;
    const double n = near * scale, f = far * scale;
    if (scene.perspective) {
        projection.m[0][0] = 1.0 / half, projection.m[1][1] = 1.0 / half * width / height;
        projection.m[2][2] = -(f + n) / (f - n), projection.m[2][3] = -2.0 * f * n / (f - n);
        projection.m[3][2] = -1.0, projection.m[3][3] = 0.0;
    } else {
        projection.m[0][0] = 1.0 / (half * scale), projection.m[1][1] = double(width) / height / (half * scale);
        projection.m[2][2] = -2.0 / (f - n), projection.m[2][3] = -(f + n) / (f - n);
    }
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {  // now and then, a raw matrix
        case 0: scene.index_to_world = consume_raw_matrix(in), scene.well_posed = false; break;
        case 1: scene.world_to_camera = consume_raw_matrix(in), scene.well_posed = false; break;
        case 2: scene.projection = consume_raw_matrix(in), scene.well_posed = false; break;
        default: break;
    }
    return scene;
}

}  // namespace pcvr::fuzz
