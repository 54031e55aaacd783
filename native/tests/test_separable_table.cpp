// SeparableFootprintTable (src/splat/phase_table.h): a pixel-averaged footprint kept as an x row and a y column
// per phase, against the whole-window PhaseFootprintTable::pixel_averaged it stands for in perspective blocks.
#include <cmath>

#include "splat/phase_table.h"
#include "unit_test.h"

using namespace pcvr;

TEST(separable_rows_are_the_whole_window_tables_axes) {
    // sigma 0.35 / 0.5 nodes on nodes a pixel apart: a 6 x 6 window (reach 2 sigma / 0.6 + 1/2).
    const double sigma_x = 0.35, sigma_y = 0.5, half_pixel = 0.5;
    const int half_width = 3;
    const SeparableFootprintTable separable(sigma_x, sigma_y, half_pixel, half_width);
    const PhaseFootprintTable whole = PhaseFootprintTable::pixel_averaged(sigma_x, sigma_y, half_pixel, half_width);
    CHECK(separable.window() == whole.window());
    const int step = SeparableFootprintTable::kPhases / whole.phases();  // 64 phases a node against 32
    CHECK(step * whole.phases() == SeparableFootprintTable::kPhases);
    double worst = 0, worst_sum = 0;
    for (int py = 0; py <= whole.phases(); ++py)
        for (int px = 0; px <= whole.phases(); ++px) {
            const float* x = separable.x(px * step);
            const float* y = separable.y(py * step);
            const float* w = whole.data() + (size_t(py) * (whole.phases() + 1) + px) * whole.entry_size();
            for (int j = 0; j < whole.window(); ++j)
                for (int i = 0; i < whole.window(); ++i) worst = std::max(worst, std::abs(double(x[i]) * y[j] - w[j * whole.pitch() + i]));
        }
    for (int p = 0; p <= SeparableFootprintTable::kPhases; ++p) {
        double sx = 0, sy = 0;
        for (int i = 0; i < SeparableFootprintTable::kMaxWindow; ++i) sx += separable.x(p)[i], sy += separable.y(p)[i];
        worst_sum = std::max({worst_sum, std::abs(sx - 1.0), std::abs(sy - 1.0)});  // lanes past the window are zero
    }
    CHECK(worst < 1e-6);
    CHECK(worst_sum < 1e-6);
}

TEST(separable_tables_resolve_narrower_footprints_than_sampled_ones) {
    // 64 phases and the pixel's box: 0.1 nodes (6.4 / 64) where a sampled footprint needs 11 / 32.
    CHECK(SeparableFootprintTable::resolves(0.11));
    CHECK(!SeparableFootprintTable::resolves(0.09));
}
