// The passband compensation's filter (src/splat/passband.h): [-a, 1 + 2a, -a] along each axis of a splat grid.
#include <cmath>

#include "pcvr/render_control.h"
#include "splat/passband.h"
#include "splat/splat_grid.h"
#include "unit_test.h"

using namespace pcvr;

namespace {

SplatGrid grid_with_one_node(int column, int row, double value) {
    SplatGrid grid(80, 60, 1.0, 0);
    grid.row(row)[column] = value;
    grid.mark(column, row, column, row);
    return grid;
}

}  // namespace

TEST(sharpening_a_node_spreads_the_separable_filter) {
    // One node: its neighbours `d` nodes away take -a (1 + 2a), the diagonal ones a^2, itself (1 + 2a)^2.
    const double a = 0.3;
    RenderControl control;
    for (int d : {1, 3}) {
        SplatGrid grid = grid_with_one_node(40, 30, 2.0);
        sharpen_nodes(grid, a, d, control);
        double sum = 0;
        for (int r = 0; r < grid.rows(); ++r)
            for (int c = 0; c < grid.columns(); ++c) sum += grid.row(r)[c];
        CHECK_NEAR(sum, 2.0, 1e-12);  // sums to one: mass stays
        CHECK_NEAR(grid.row(30)[40], 2.0 * (1 + 2 * a) * (1 + 2 * a), 1e-12);
        CHECK_NEAR(grid.row(30)[40 + d], -2.0 * a * (1 + 2 * a), 1e-12);
        CHECK_NEAR(grid.row(30 - d)[40], -2.0 * a * (1 + 2 * a), 1e-12);
        CHECK_NEAR(grid.row(30 + d)[40 - d], 2.0 * a * a, 1e-12);
        CHECK(grid.row(30)[40 + d + 1] == 0.0 && grid.row(30 + 1)[40] == (d == 1 ? -2.0 * a * (1 + 2 * a) : 0.0));
    }
}

TEST(sharpening_keeps_constants_and_takes_back_a_variance) {
    // A constant region stays constant inside; the filter's second moment per axis is -2a, so a = blur / 2
    // (times kPassbandStrength) takes back `blur` nodes^2.
    SplatGrid grid(64, 64, 1.0, 0);
    for (int r = 0; r < grid.rows(); ++r)
        for (int c = 0; c < grid.columns(); ++c) grid.row(r)[c] = 1.5;
    grid.mark(0, 0, grid.columns() - 1, grid.rows() - 1);
    RenderControl control;
    sharpen_nodes(grid, 0.25, 1, control);
    for (int r = 1; r < grid.rows() - 1; ++r)
        for (int c = 1; c < grid.columns() - 1; ++c) CHECK_NEAR(grid.row(r)[c], 1.5, 1e-12);
    CHECK_NEAR(passband_sharpening(0.5), 0.25 * kPassbandStrength, 1e-12);
    CHECK(passband_sharpening(0.0) == 0.0 && passband_sharpening(-1.0) == 0.0);
}
