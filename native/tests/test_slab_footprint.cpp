// The depth profile D(s) behind every slab footprint (src/splat/slab_footprint.h).
#include <cmath>

#include "pcvr/kernel.h"
#include "pcvr/lanes.h"
#include "splat/slab_footprint.h"
#include "unit_test.h"

using namespace pcvr;

TEST(depth_profile_of_the_gaussians_is_their_normalised_erf) {
    for (KernelShape shape : {KernelShape::Gauss14, KernelShape::Gauss20}) {
        const Kernel kernel(shape);
        const DepthProfile D(kernel);
        const double a = shape == KernelShape::Gauss14 ? 1.4 : 2.0, R = kernel.radius();
        // The fit's error (1e-6, 7e-6 for gauss2.0) plus float rounding.
        const double tolerance = shape == KernelShape::Gauss14 ? 2e-6 : 1e-5;
        for (int i = 0; i <= 1000; ++i) {
            const double s = -R + 2.0 * R * i / 1000.0;
            CHECK_NEAR(D(float(s)), 0.5 * (1.0 + std::erf(std::sqrt(a) * s) / std::erf(std::sqrt(a) * R)), tolerance);
        }
    }
}

TEST(depth_profile_runs_from_zero_to_one_and_never_decreases) {
    for (KernelShape shape : {KernelShape::Gauss14, KernelShape::Gauss20, KernelShape::Linear, KernelShape::Box}) {
        const Kernel kernel(shape);
        const DepthProfile D(kernel);
        const float R = float(kernel.radius());
        CHECK(D(-R) == 0.0f && D(R) == 1.0f);  // a voxel's slabs add up to its whole footprint
        CHECK(D(-10 * R) == 0.0f && D(10 * R) == 1.0f);
        // Monotone up to the fit's ripple where the profile is flattest (gauss2.0 at its rim: exp(-8) of
        // the peak; measured 1.4e-6) and the rounding of the polynomial in float.
        float previous = D(-R);
        for (int i = 1; i <= 4000; ++i) {
            const float next = D(-R + 2 * R * float(i) / 4000.0f);
            CHECK(next >= previous - 2e-6f && next >= 0.0f && next <= 1.0f);
            previous = next;
        }
    }
}

TEST(depth_profile_of_linear_and_box_kernels_in_closed_form) {
    const DepthProfile linear{Kernel(KernelShape::Linear)}, box{Kernel(KernelShape::Box)};
    const double Rb = Kernel(KernelShape::Box).radius();
    for (int i = 0; i <= 100; ++i) {
        const double t = -1.0 + 2.0 * i / 100.0;
        // 1 - |s| integrated from -1 (radius 1), and a constant over the chord.
        CHECK_NEAR(linear(float(t)), t < 0 ? 0.5 * (1 + t) * (1 + t) : 1 - 0.5 * (1 - t) * (1 - t), 1e-6);
        CHECK_NEAR(box(float(t * Rb)), 0.5 * (1 + t), 1e-6);
    }
}

TEST(depth_profile_lanes_match_the_scalar_call) {
    const DepthProfile D{Kernel(KernelShape::Gauss14)};
    const float8 s = {-2.5f, -1.7f, -0.4f, 0.0f, 0.3f, 1.1f, 1.99f, 3.0f};
    const float8 lanes = D(s, [](float8 t) { return clamp8(t, -1.0f, 1.0f); }, [](float8 t) { return abs8(t); });
    for (int l = 0; l < 8; ++l) CHECK(lanes[l] == D(s[l]));
}
