// FootprintTable: the per-tap footprint weights the perspective splats (X-ray and shaded) take, eight at a
// time, from a polynomial in rho^2 where it fits the kernel's line integral closer than the table.
#include <cmath>

#include "pcvr/kernel.h"
#include "unit_test.h"

using namespace pcvr;

TEST(footprint_weights_follow_the_line_integral_at_least_as_closely_as_the_table) {
    for (const char* name : {"gauss1.4", "gauss2.0", "linear", "box"}) {
        const Kernel kernel = Kernel::from_name(name);
        const FootprintTable table(kernel);
        const double r2 = kernel.radius() * kernel.radius();
        double worst = 0, worst_table = 0;
        for (int k = 0; k < 4000; k += 8) {
            float8 rho2;
            for (int l = 0; l < 8; ++l) rho2[l] = float(r2 * (k + l) / 4000.0);
            const float8 w = table.weights(rho2);
            for (int l = 0; l < 8; ++l) {
                const double exact = kernel.line_integral(std::sqrt(double(rho2[l])));
                worst = std::max(worst, std::abs(w[l] - exact));
                worst_table = std::max(worst_table, std::abs(table.at_rho2(rho2[l]) - exact));
            }
        }
        CHECK(worst <= worst_table * 1.0001);
        // Beyond the radius nothing; below zero (a rounded quadratic form) the centre.
        const float8 outside = table.weights(float8{} + float(r2) * 1.001f), below = table.weights(float8{} - 1e-6f);
        CHECK(outside[0] == 0.0f && outside[7] == 0.0f);
        CHECK_NEAR(below[3], kernel.line_integral(0.0), 2e-3 * kernel.line_integral(0.0));
    }
    // The Gaussians take the polynomial (the box's rim, a square root, fits no polynomial).
    CHECK(FootprintTable(Kernel::from_name("gauss1.4")).fitted() && FootprintTable(Kernel::from_name("gauss2.0")).fitted());
    CHECK(!FootprintTable(Kernel::from_name("box")).fitted());
}
