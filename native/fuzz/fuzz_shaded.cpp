/// @file fuzz_shaded.cpp
/// @brief libFuzzer target: render_shaded and render_mip over random scenes, transfer functions,
/// lights and options.
///
/// The scene (volume, transform, camera inside or outside, scaled by 1e-9 to 1e9 and moved up to 1e8
/// units out, now and then a raw matrix) is fuzz_render's (fuzz_scene.h). On top of it the input
/// chooses one or two volumes of that grid, each with a transfer function (up to five control points
/// over the values' range, opacities from 0 to 1, colours up to 4, unit_distance from 1e-3 to 1e3
/// voxels or the voxel spacing), a material now and then, lights (suns, and point lights at the eye,
/// at a voxel's centre, on the view axis or anywhere; strengths from 1e-3 to 1e3, now and then any
/// double), and every option: method, kernel, post filter, stride, sheet_spacing, samples_per_sheet,
/// tile_size, opacity_cutoff, depth, culling.
///
/// Only pcvr errors may come out. The shaded image must be finite, its alpha in [0, 1] and its
/// premultiplied colour >= 0; the depth pass a depth or infinity; MIP finite. A violation aborts, and
/// libFuzzer keeps the input. PCVR_FUZZ_SCENE=1 prints the scene and the options as Python.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "fuzz_scene.h"
#include "pcvr/errors.h"
#include "pcvr/shaded.h"

namespace {

using namespace pcvr;

/// Renders of more pixels than this (fewer where samples are denser than 1 per voxel) take too long for
/// a fuzzing iteration; the ray caster samples every voxel within the kernel's reach per step, so it
/// gets fewer pixels and coarser steps.
constexpr uint64_t kMaxPixels = 1 << 16;
constexpr uint64_t kMaxRaycastPixels = 4096;
constexpr double kFinestRaycastSpacing = 0.1;

/// 1 to 5 control points from -2.5 to 7.5 times the values' magnitude; a step of 0 (densities that
/// do not increase) is refused by validate().
TransferFunction consume_transfer_function(FuzzedDataProvider& in, const fuzz::Scene& scene) {
    TransferFunction tf;
    const int points = in.ConsumeIntegralInRange<int>(1, 5);
    double density = in.ConsumeFloatingPointInRange(-2.5, 2.5);
    for (int i = 0; i < points; ++i) {
        tf.density.push_back(density * scene.magnitude);
        density += in.ConsumeBool() ? 0.0 : in.ConsumeFloatingPointInRange(0.0, 2.0);
        const int kind = in.ConsumeIntegralInRange<int>(0, 2);  // transparent, opaque or between
        const double opacity = kind < 2 ? double(kind) : in.ConsumeProbability<double>();
        tf.rgba.push_back({in.ConsumeFloatingPointInRange(0.0, 4.0), in.ConsumeFloatingPointInRange(0.0, 4.0),
                           in.ConsumeFloatingPointInRange(0.0, 4.0), opacity});
    }
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: tf.unit_distance = 0.0; break;  // the voxel spacing
        case 1: tf.unit_distance = scene.scale * std::pow(10.0, in.ConsumeFloatingPointInRange(-3.0, 3.0)); break;
        case 2: tf.unit_distance = std::pow(10.0, in.ConsumeFloatingPointInRange(-20.0, 20.0)); break;
        default: tf.unit_distance = in.ConsumeFloatingPoint<double>(); break;
    }
    return tf;
}

Shading consume_shading(FuzzedDataProvider& in) {
    Shading s;
    s.ambient = in.ConsumeFloatingPointInRange(0.0, 2.0);
    s.diffuse = in.ConsumeFloatingPointInRange(0.0, 2.0);
    s.specular = in.ConsumeFloatingPointInRange(0.0, 2.0);
    s.shininess = in.ConsumeBool() ? in.ConsumeFloatingPointInRange(0.0, 200.0) : in.ConsumeFloatingPoint<double>();
    s.lit = in.ConsumeIntegralInRange<int>(0, 7) != 0;
    return s;
}

Light consume_light(FuzzedDataProvider& in, const fuzz::Scene& scene) {
    Light light;
    light.color = {in.ConsumeFloatingPointInRange(0.0, 2.0), in.ConsumeFloatingPointInRange(0.0, 2.0),
                   in.ConsumeFloatingPointInRange(0.0, 2.0)};
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: light.strength = std::pow(10.0, in.ConsumeFloatingPointInRange(-3.0, 3.0)); break;
        case 1: light.strength = std::pow(10.0, in.ConsumeFloatingPointInRange(-40.0, 40.0)); break;
        case 2: light.strength = in.ConsumeFloatingPoint<double>(); break;
        default: break;  // 1
    }
    if (in.ConsumeBool()) {
        light.kind = Light::Kind::Sun;
        light.vector = fuzz::consume_vec(in, 1.0);
        return light;
    }
    light.kind = Light::Kind::Point;
    const Mat4& w2c = scene.world_to_camera;
    const Vec3 forward = -Vec3{w2c.m[2][0], w2c.m[2][1], w2c.m[2][2]};  // unit unless the matrix is raw
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: light.vector = scene.eye_world; break;
        case 1: {  // a voxel's centre, where samples of the sheets and the ray caster can lie
            const Vec3 index{double(in.ConsumeIntegralInRange<size_t>(0, scene.shape[0] - 1)),
                             double(in.ConsumeIntegralInRange<size_t>(0, scene.shape[1] - 1)),
                             double(in.ConsumeIntegralInRange<size_t>(0, scene.shape[2] - 1))};
            light.vector = scene.index_to_world.transform_point(index);
            break;
        }
        case 2: light.vector = scene.eye_world + forward * (scene.scale * in.ConsumeFloatingPointInRange(0.0, 50.0)); break;
        default: light.vector = scene.eye_world + fuzz::consume_vec(in, 40.0) * scene.scale; break;
    }
    return light;
}

ShadedParams consume_params(FuzzedDataProvider& in) {
    ShadedParams p;
    p.method = in.PickValueInArray({ShadedMethod::Pcvr, ShadedMethod::Regular, ShadedMethod::BilinearSpread, ShadedMethod::Raycast});
    p.splat_kernel = in.PickValueInArray({"gauss1.4", "gauss2.0", "linear", "box"});
    p.post_filter = in.PickValueInArray({"catmull_rom", "bilinear", "gauss1.4", "gauss2.0"});
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: p.stride = in.ConsumeIntegralInRange<int>(1, 16); break;
        case 1: p.stride = in.ConsumeIntegralInRange<int>(-1, 70000); break;
        default: break;  // automatic
    }
    p.sheet_spacing = in.ConsumeIntegralInRange<int>(0, 7) == 0 ? in.ConsumeFloatingPoint<double>()
                                                                : std::pow(10.0, in.ConsumeFloatingPointInRange(-1.5, 1.5));
    p.samples_per_sheet = in.ConsumeIntegralInRange<int>(0, 7) == 0 ? in.ConsumeIntegralInRange<int>(-1, 65)
                                                                    : in.ConsumeIntegralInRange<int>(1, 4);
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
        case 0: p.opacity_cutoff = 1.0; break;
        case 1: p.opacity_cutoff = in.ConsumeFloatingPointInRange(-0.1, 1.1); break;
        default: break;  // 0.99
    }
    p.tile_size = in.ConsumeBool() ? 0 : in.ConsumeIntegralInRange<int>(-1, 300);
    p.depth = in.ConsumeBool();
    p.cull_transparent = in.ConsumeIntegralInRange<int>(0, 7) != 0;
    p.threads = 1;
    return p;
}

void print_params(const ShadedParams& p, const std::vector<TransferFunction>& tfs, const std::vector<double>& density_scales,
                  const Lighting& lighting) {
    static const char* methods[] = {"regular", "pcvr", "bilinear_spread", "raycast"};
    std::fprintf(stderr, "method = '%s'\nsplat_kernel, post_filter = '%s', '%s'\nstride = %d\nsheet_spacing = %.17g\n"
                 "samples_per_sheet = %d\nopacity_cutoff = %.17g\ntile_size = %d\ndepth = %d\ncull_transparent = %d\n",
                 methods[int(p.method)], p.splat_kernel.c_str(), p.post_filter.c_str(), p.stride, p.sheet_spacing,
                 p.samples_per_sheet, p.opacity_cutoff, p.tile_size, int(p.depth), int(p.cull_transparent));
    for (size_t v = 0; v < tfs.size(); ++v) {
        std::fprintf(stderr, "volume %zu: density_scale = %.17g, unit_distance = %.17g\n", v, density_scales[v], tfs[v].unit_distance);
        for (size_t i = 0; i < tfs[v].density.size(); ++i) {
            const auto& c = tfs[v].rgba[i];
            std::fprintf(stderr, "  (%.17g, [%.17g, %.17g, %.17g, %.17g])\n", tfs[v].density[i], c[0], c[1], c[2], c[3]);
        }
    }
    const Shading& m = lighting.material;
    std::fprintf(stderr, "ambient = [%.17g, %.17g, %.17g]\nmaterial = (%.17g, %.17g, %.17g, %.17g, lit=%d)\n", lighting.ambient.x,
                 lighting.ambient.y, lighting.ambient.z, m.ambient, m.diffuse, m.specular, m.shininess, int(m.lit));
    for (const Light& l : lighting.lights)
        std::fprintf(stderr, "light %s [%.17g, %.17g, %.17g] colour [%.17g, %.17g, %.17g] strength %.17g\n",
                     l.kind == Light::Kind::Sun ? "sun" : "point", l.vector.x, l.vector.y, l.vector.z, l.color.x, l.color.y,
                     l.color.z, l.strength);
}

void check(bool ok, const char* what, size_t pixel, float value) {
    if (ok) return;
    std::fprintf(stderr, "%s at pixel %zu: %g\n", what, pixel, double(value));
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    FuzzedDataProvider in(data, size);
    fuzz::Scene scene = fuzz::consume_scene(in);

    const int volume_count = in.ConsumeIntegralInRange<int>(1, 2);
    std::vector<TransferFunction> transfer_functions;
    std::vector<Shading> materials;
    std::vector<double> density_scales;
    for (int v = 0; v < volume_count; ++v) {
        transfer_functions.push_back(consume_transfer_function(in, scene));
        density_scales.push_back(in.ConsumeIntegralInRange<int>(0, 7) == 0 ? in.ConsumeFloatingPoint<double>()
                                                                           : in.ConsumeFloatingPointInRange(0.0, 3.0));
        if (in.ConsumeBool()) materials.push_back(consume_shading(in));
    }
    Lighting lighting;
    lighting.ambient = {in.ConsumeFloatingPointInRange(0.0, 1.0), in.ConsumeFloatingPointInRange(0.0, 1.0),
                        in.ConsumeFloatingPointInRange(0.0, 1.0)};
    lighting.material = consume_shading(in);
    for (int l = in.ConsumeIntegralInRange<int>(0, 3); l > 0; --l) lighting.lights.push_back(consume_light(in, scene));
    ShadedParams params = consume_params(in);

    // Bounded time: fewer pixels where the samples along the rays are dense (the aspect ratio changes;
    // any is valid; a 60000 x 1 image at 5 samples per 0.1 voxels took 35 s), and the ray caster coarser.
    const double samples_per_voxel = std::max(1, params.samples_per_sheet) / std::clamp(params.sheet_spacing, 0.02, 1.0);
    const int most_pixels = int(std::max(64.0, double(kMaxPixels) / samples_per_voxel));
    if (uint64_t(scene.width) * scene.height > uint64_t(most_pixels)) {
        scene.width = std::min(scene.width, most_pixels);
        scene.height = std::max(1, most_pixels / scene.width);
    }
    if (params.method == ShadedMethod::Raycast &&
        (uint64_t(scene.width) * scene.height > kMaxRaycastPixels || !(params.sheet_spacing >= kFinestRaycastSpacing)))
        params.method = ShadedMethod::Pcvr;

    if (std::getenv("PCVR_FUZZ_SCENE")) {
        scene.print();
        print_params(params, transfer_functions, density_scales, lighting);
    }
    try {
        const Grid grid = scene.grid();
        const Camera camera = scene.camera();
        std::vector<ShadedVolume> volumes;
        for (int v = 0; v < volume_count; ++v)
            volumes.push_back({&grid, &transfer_functions[v], density_scales[v], v < int(materials.size()) ? &materials[v] : nullptr});
        try {
            RenderControl control;
            const RgbaImage image = render_shaded(volumes, camera, lighting, params, control);
            for (size_t p = 0; p < image.pixels.size() / 4; ++p) {
                const float* rgba = image.pixels.data() + 4 * p;
                for (int c = 0; c < 3; ++c) check(std::isfinite(rgba[c]) && rgba[c] >= 0, "colour not finite or negative", p, rgba[c]);
                check(rgba[3] >= 0 && rgba[3] <= 1, "alpha outside [0, 1]", p, rgba[3]);
            }
            for (size_t p = 0; p < image.depth.size(); ++p) check(!std::isnan(image.depth[p]), "depth NaN", p, image.depth[p]);
        } catch (const Error&) {
        }
        RenderControl control;  // MIP needs no transfer function or lights: it runs where they are refused
        const MipImage mip = render_mip(volumes, camera, params, control);
        for (size_t p = 0; p < mip.pixels.size(); ++p) check(std::isfinite(mip.pixels[p]), "MIP not finite", p, mip.pixels[p]);
    } catch (const Error&) {
    }
    return 0;
}
