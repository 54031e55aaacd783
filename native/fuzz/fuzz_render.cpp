/// @file fuzz_render.cpp
/// @brief libFuzzer target: grid and camera parameters for render_xray.
///
/// The input chooses a small volume (up to 6^3 voxels, values from denormal to 1e30, any sign), an
/// index-to-world transform (rotation, anisotropic scale, shear, mirror), a camera (orthographic or
/// perspective, outside or inside the volume, any clip range and image shape) and the render's
/// options, in a unit-scale scene that is then scaled by 1e-9 to 1e9 and moved up to 1e8 units out.
/// Some inputs replace a matrix by raw doubles (NaN, infinities, singular ones).
///
/// Only pcvr errors may come out. On top of that, where the scene is well-posed (structured, within
/// what double precision resolves), regular must stay within 6% of exact's peak: the 4% a
/// linearised footprint may be off plus the footprint table's error and a margin (property tests
/// measured 2%). A violation aborts, and libFuzzer keeps the input.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "fuzz_scene.h"
#include "pcvr/errors.h"

namespace {

using pcvr::Mat4;
using pcvr::Vec3;

Mat4 rotation(Vec3 axis, double angle) {
    const double n = pcvr::length(axis);
    axis = n > 0 ? axis / n : Vec3{0, 0, 1};
    const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
    Mat4 r;
    const double x = axis.x, y = axis.y, z = axis.z;
    r.m[0][0] = t * x * x + c, r.m[0][1] = t * x * y - s * z, r.m[0][2] = t * x * z + s * y;
    r.m[1][0] = t * x * y + s * z, r.m[1][1] = t * y * y + c, r.m[1][2] = t * y * z - s * x;
    r.m[2][0] = t * x * z - s * y, r.m[2][1] = t * y * z + s * x, r.m[2][2] = t * z * z + c;
    return r;
}

Vec3 consume_vec(FuzzedDataProvider& in, double range) {
    return {in.ConsumeFloatingPointInRange(-range, range), in.ConsumeFloatingPointInRange(-range, range),
            in.ConsumeFloatingPointInRange(-range, range)};
}

Mat4 consume_raw_matrix(FuzzedDataProvider& in) {
    Mat4 m;
    for (auto& row : m.m)
        for (double& v : row) v = in.ConsumeFloatingPoint<double>();
    return m;
}

/// world_to_camera for an eye looking at `target` (camera looks down -Z).
Mat4 look_at(const Vec3& eye, const Vec3& target, Vec3 up) {
    Vec3 f = target - eye;
    if (!(pcvr::length(f) > 0)) f = {0, 0, -1};
    f = f / pcvr::length(f);
    if (std::abs(pcvr::dot(f, up / std::max(pcvr::length(up), 1e-300))) > 0.99 || !(pcvr::length(up) > 0))
        up = std::abs(f.y) < 0.9 ? Vec3{0, 1, 0} : Vec3{1, 0, 0};
    Vec3 x = pcvr::cross(f, up);
    x = x / pcvr::length(x);
    const Vec3 y = pcvr::cross(x, f);
    Mat4 m;
    const Vec3 rows[3] = {x, y, -f};
    for (int r = 0; r < 3; ++r) {
        m.m[r][0] = rows[r].x, m.m[r][1] = rows[r].y, m.m[r][2] = rows[r].z;
        m.m[r][3] = -pcvr::dot(rows[r], eye);
    }
    return m;
}

void print_matrix(const char* name, const Mat4& m) {
    std::fprintf(stderr, "%s = [", name);
    for (int r = 0; r < 4; ++r)
        std::fprintf(stderr, "[%.17g, %.17g, %.17g, %.17g]%s", m.m[r][0], m.m[r][1], m.m[r][2], m.m[r][3], r < 3 ? ", " : "]\n");
}

Mat4 scaled_by(const Mat4& m, double scale, const Vec3& offset) {
    Mat4 s;
    s.m[0][0] = s.m[1][1] = s.m[2][2] = scale;
    s.m[0][3] = offset.x, s.m[1][3] = offset.y, s.m[2][3] = offset.z;
    return s * m;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    FuzzedDataProvider in(data, size);
    bool well_posed = true;

    // The volume: values in [-2, 2] times a power of ten from 1e-44 to 1e30, about half zero.
    const size_t nx = in.ConsumeIntegralInRange<size_t>(1, 6), ny = in.ConsumeIntegralInRange<size_t>(1, 6),
                 nz = in.ConsumeIntegralInRange<size_t>(1, 6);
    const float magnitude = float(std::pow(10.0, in.ConsumeIntegralInRange<int>(-44, 30)));
    const bool signed_values = in.ConsumeBool();
    std::vector<float> values(nx * ny * nz);
    for (float& v : values) {
        const uint8_t byte = in.ConsumeIntegral<uint8_t>();
        v = byte < 128 ? 0.0f : magnitude * float(byte - 127) / 64.0f * (signed_values && (byte & 1) ? -1.0f : 1.0f);
    }

    // The transform: rotation x scale x shear x mirror, centred, then scaled and moved.
    Mat4 linear = rotation(consume_vec(in, 1.0), in.ConsumeFloatingPointInRange(0.0, 7.0));
    Mat4 shape;
    for (int a = 0; a < 3; ++a) shape.m[a][a] = in.ConsumeFloatingPointInRange(0.2, 5.0) * (a == 0 && in.ConsumeBool() ? -1 : 1);
    shape.m[0][1] = in.ConsumeFloatingPointInRange(-0.6, 0.6);
    shape.m[1][2] = in.ConsumeFloatingPointInRange(-0.6, 0.6);
    Mat4 index_to_world = linear * shape;
    const Vec3 centre = index_to_world.transform_vector({(nx - 1) / 2.0, (ny - 1) / 2.0, (nz - 1) / 2.0});
    for (int r = 0; r < 3; ++r) index_to_world.m[r][3] = -centre[r];

    // The camera, in the volume's unit-scale frame: inside it or up to 40 units out.
    const bool perspective = in.ConsumeBool();
    const Vec3 eye = in.ConsumeBool() ? consume_vec(in, 2.0) : consume_vec(in, 40.0);
    const Mat4 view = look_at(eye, consume_vec(in, 3.0), consume_vec(in, 1.0));
    const double near = std::pow(10.0, in.ConsumeFloatingPointInRange(-4.0, 1.0));
    const double far = near * std::pow(10.0, in.ConsumeFloatingPointInRange(0.5, 12.0));
    const double half = in.ConsumeFloatingPointInRange(0.05, 40.0);  // orthographic half width, or tan(fov / 2)
    int width = in.ConsumeIntegralInRange<int>(1, 40), height = in.ConsumeIntegralInRange<int>(1, 40);
    if (in.ConsumeIntegralInRange<int>(0, 15) == 0) (in.ConsumeBool() ? width : height) = in.ConsumeIntegralInRange<int>(1, 1 << 16);

    // Scale and offset of the whole scene.
    const double scale = std::pow(10.0, in.ConsumeFloatingPointInRange(-9.0, 9.0));
    const Vec3 offset = scale >= 1e-2 && in.ConsumeBool() ? consume_vec(in, 1e8) : Vec3{};
    index_to_world = scaled_by(index_to_world, scale, offset);
    // The view's rotation from the unit-scale frame (1e8 out, target - eye would round), its
    // translation from where the eye now is.
    Mat4 world_to_camera = view;
    const Vec3 eye_world = eye * scale + offset;
    for (int r = 0; r < 3; ++r)
        world_to_camera.m[r][3] = -(view.m[r][0] * eye_world.x + view.m[r][1] * eye_world.y + view.m[r][2] * eye_world.z);
    Mat4 projection;
    const double n = near * scale, f = far * scale;
    if (perspective) {
        projection.m[0][0] = 1.0 / half, projection.m[1][1] = 1.0 / half * width / height;
        projection.m[2][2] = -(f + n) / (f - n), projection.m[2][3] = -2.0 * f * n / (f - n);
        projection.m[3][2] = -1.0, projection.m[3][3] = 0.0;
    } else {
        projection.m[0][0] = 1.0 / (half * scale), projection.m[1][1] = double(width) / height / (half * scale);
        projection.m[2][2] = -2.0 / (f - n), projection.m[2][3] = -(f + n) / (f - n);
    }
    switch (in.ConsumeIntegralInRange<int>(0, 15)) {  // now and then, a raw matrix
        case 0: index_to_world = consume_raw_matrix(in), well_posed = false; break;
        case 1: world_to_camera = consume_raw_matrix(in), well_posed = false; break;
        case 2: projection = consume_raw_matrix(in), well_posed = false; break;
        default: break;
    }

    pcvr::XrayParams params;
    params.method = in.PickValueInArray({pcvr::XrayMethod::Regular, pcvr::XrayMethod::Pcvr,
                                         pcvr::XrayMethod::BilinearSpread, pcvr::XrayMethod::Exact});
    params.splat_kernel = in.PickValueInArray({"gauss1.4", "gauss2.0", "linear", "box"});
    params.post_filter = in.PickValueInArray({"bilinear", "gauss1.4", "gauss2.0"});
    params.stride = in.ConsumeBool() ? 0 : in.ConsumeIntegralInRange<int>(-1, 70000);
    params.footprint_tolerance = in.ConsumeBool() ? 0.04 : in.ConsumeFloatingPointInRange(0.0, 1.0);
    const double density_scale = in.ConsumeBool() ? 1.0 : in.ConsumeFloatingPoint<double>();

    // PCVR_FUZZ_SCENE=1: print the scene as Python, to turn a finding into a test.
    if (std::getenv("PCVR_FUZZ_SCENE")) {
        std::fprintf(stderr, "shape = (%zu, %zu, %zu)\nvalues = [", nx, ny, nz);
        for (float v : values) std::fprintf(stderr, "%.9g, ", v);
        std::fprintf(stderr, "]\n");
        print_matrix("index_to_world", index_to_world);
        print_matrix("world_to_camera", world_to_camera);
        print_matrix("projection", projection);
        std::fprintf(stderr, "width, height = %d, %d\nmethod = %d\nkernel, post = %s, %s\nstride = %d\n"
                     "footprint_tolerance = %.17g\ndensity_scale = %.17g\n", width, height, int(params.method),
                     params.splat_kernel.c_str(), params.post_filter.c_str(), params.stride, params.footprint_tolerance,
                     density_scale);
    }
    try {
        const pcvr::Grid grid = pcvr::Grid::from_dense(values.data(), {nx, ny, nz}, index_to_world, 0.0f);
        const pcvr::Camera camera(world_to_camera, projection, width, height);
        params.threads = 1;
        params.memory_limit = pcvr::fuzz::kMemoryLimit;
        pcvr::RenderControl control;
        const pcvr::XrayImage image = pcvr::render_xray({{&grid, density_scale}}, camera, params, control);
        for (float p : image.pixels)
            if (!std::isfinite(p)) std::abort();  // render_xray promises finite pixels or an error

        // regular against exact, where the scene is well-posed and small enough to compare.
        const bool comparable = well_posed && params.method == pcvr::XrayMethod::Regular && density_scale == 1.0 &&
                                params.footprint_tolerance == 0.04 && uint64_t(width) * height <= 4096;
        if (comparable) {
            pcvr::XrayParams exact = params;
            exact.method = pcvr::XrayMethod::Exact;
            pcvr::RenderControl exact_control;
            const pcvr::XrayImage reference = pcvr::render_xray({{&grid, 1.0}}, camera, exact, exact_control);
            double peak = 0, error = 0;
            for (size_t i = 0; i < reference.pixels.size(); ++i) {
                peak = std::max(peak, std::abs(double(reference.pixels[i])));
                error = std::max(error, std::abs(double(image.pixels[i]) - double(reference.pixels[i])));
            }
            if (peak > 0 && std::isnormal(peak) && error > 0.06 * peak) {
                std::fprintf(stderr, "regular differs from exact by %g of the peak %g\n", error / peak, peak);
                std::abort();
            }
        }
    } catch (const pcvr::Error&) {
    }
    return 0;
}
