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
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "fuzz_scene.h"
#include "pcvr/errors.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    FuzzedDataProvider in(data, size);
    const pcvr::fuzz::Scene scene = pcvr::fuzz::consume_scene(in);
    const int width = scene.width, height = scene.height;

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
        scene.print();
        std::fprintf(stderr, "method = %d\nkernel, post = %s, %s\nstride = %d\n"
                     "footprint_tolerance = %.17g\ndensity_scale = %.17g\n", int(params.method),
                     params.splat_kernel.c_str(), params.post_filter.c_str(), params.stride, params.footprint_tolerance,
                     density_scale);
    }
    try {
        const pcvr::Grid grid = scene.grid();
        const pcvr::Camera camera = scene.camera();
        params.threads = 1;
        params.memory_limit = pcvr::fuzz::kMemoryLimit;
        pcvr::RenderControl control;
        const pcvr::XrayImage image = pcvr::render_xray({{&grid, density_scale}}, camera, params, control);
        for (float p : image.pixels)
            if (!std::isfinite(p)) std::abort();  // render_xray promises finite pixels or an error

        // regular against exact, where the scene is well-posed and small enough to compare.
        const bool comparable = scene.well_posed && params.method == pcvr::XrayMethod::Regular && density_scale == 1.0 &&
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
