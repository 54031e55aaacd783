// Clip regions (pcvr/clip_region.h) and the kept part of a kernel's line integral (Kernel::segment_integral):
// what the X-ray's cut voxels and the exact reference integrate.
#include <cmath>
#include <string>

#include "pcvr/clip_region.h"
#include "pcvr/errors.h"
#include "pcvr/kernel.h"
#include "unit_test.h"

using namespace pcvr;

namespace {

/// integral of h(sqrt(rho^2 + s^2)) ds over [s0, s1] by composite Simpson, fine enough to judge.
double simpson_segment(const Kernel& k, double rho, double s0, double s1) {
    const int n = 20000;
    const double h = (s1 - s0) / n;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
        const double s = s0 + i * h;
        const double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
        sum += w * k.value(std::sqrt(rho * rho + s * s));
    }
    return sum * h / 3.0;
}

bool throws_invalid(const std::vector<ClipPlane>& planes, const Mat4* box, const std::string& words) {
    try {
        ClipRegion::from(planes, box);
    } catch (const InvalidArgument& e) {
        return std::string(e.what()).find(words) != std::string::npos;
    }
    return false;
}

}  // namespace

TEST(segment_integral_matches_quadrature_and_adds_up_to_the_line_integral) {
    for (const char* name : {"gauss1.4", "gauss2.0", "linear", "box"}) {
        const Kernel k = Kernel::from_name(name);
        const double R = k.radius();
        for (double rho : {0.0, 0.2 * R, 0.55 * R, 0.9 * R}) {
            // The whole line, and the two halves of a cut anywhere along it, add up.
            CHECK_NEAR(k.segment_integral(rho, -1e300, 1e300), k.line_integral(rho), 1e-12);
            for (double cut : {-0.7 * R, -0.1 * R, 0.0, 0.3 * R, 0.95 * R}) {
                const double before = k.segment_integral(rho, -1e300, cut), after = k.segment_integral(rho, cut, 1e300);
                CHECK_NEAR(before + after, k.line_integral(rho), 1e-12);
                // Quadrature over the chord's part beyond the cut (Simpson across the linear kernel's kink at the
                // centre is good to ~1e-8; the box's rim is a jump: coarser).
                const double half = std::sqrt(std::max(R * R - rho * rho, 0.0));
                if (cut < half) CHECK_NEAR(after, simpson_segment(k, rho, cut, half), k.smooth_footprint() ? 1e-7 : 1e-3);
            }
        }
        CHECK(k.segment_integral(R, -1.0, 1.0) == 0.0);
        CHECK(k.segment_integral(0.0, 0.5, 0.2) == 0.0);  // an empty interval keeps nothing
    }
}

TEST(a_crop_box_is_six_planes_of_its_unit_cube) {
    // World-to-box: the box [1, 3] x [-1, 1] x [0, 10] (centre (2, 0, 5), half-sizes (1, 1, 5)).
    Mat4 m;
    m.m[0][0] = 1.0, m.m[0][3] = -2.0;
    m.m[2][2] = 0.2, m.m[2][3] = -1.0;
    const ClipRegion box = ClipRegion::from({}, &m);
    CHECK(box.planes().size() == 6);
    const RayInterval along_x = box.ray_interval({0, 0, 5}, {1, 0, 0}, -1e300, 1e300);
    CHECK_NEAR(along_x.lo, 1.0, 1e-12);
    CHECK_NEAR(along_x.hi, 3.0, 1e-12);
    CHECK(box.ray_interval({0, 5, 5}, {1, 0, 0}, -1e300, 1e300).empty());  // parallel to the y faces, outside
    // In index space with voxels 0.5 apart: spheres of radius 2 voxels (1 world unit).
    Mat4 half;
    half.m[0][0] = half.m[1][1] = half.m[2][2] = 0.5;
    const ClipRegion index = box.in_index_space(half);
    CHECK(index.sphere_side({4, 0, 10}, 2.0) == ClipSide::Inside);      // world (2, 0, 5): the centre
    CHECK(index.sphere_side({4, 1, 10}, 2.0) == ClipSide::Straddles);   // world y 0.5: the face y = 1 within 1
    CHECK(index.sphere_side({10, 0, 10}, 2.0) == ClipSide::Outside);    // world x 5: 2 beyond the face x = 3
    CHECK(index.box_side({0, -8, 0}, {7, -4, 7}, 2.0) == ClipSide::Outside);
    CHECK(index.box_side({3, -1, 3}, {5, 1, 5}, 0.5) == ClipSide::Inside);
}

TEST(bad_planes_and_boxes_are_refused_by_name) {
    CHECK(throws_invalid({{{0, 0, 0}, 1.0}}, nullptr, "clip plane 0: its normal (a, b, c) is zero"));
    CHECK(throws_invalid({{{1, 0, 0}, 0.0}, {{NAN, 0, 0}, 1.0}}, nullptr, "clip plane 1"));
    Mat4 empty;
    empty.m[1][1] = 0.0;
    CHECK(throws_invalid({}, &empty, "singular (an empty box)"));
    Mat4 projective;
    projective.m[3][2] = 1.0;
    CHECK(throws_invalid({}, &projective, "affine"));
    Mat4 nan;
    nan.m[0][3] = NAN;
    CHECK(throws_invalid({}, &nan, "finite"));
}
