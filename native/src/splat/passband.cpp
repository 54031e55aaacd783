#include "splat/passband.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <vector>

namespace pcvr {

double passband_sharpening(double blur) { return blur > 0 ? 0.5 * kPassbandStrength * blur : 0.0; }

namespace {

/// The nodes any splat touched, widened by `reach` nodes on every side (clamped to the grid): rows
/// [r0, r1) and columns [c0, c1); empty when nothing was touched.
struct NodeBox {
    int r0, r1, c0, c1;
};

NodeBox touched_box(const SplatGrid& grid, int reach) {
    int tx0 = grid.tiles_x(), tx1 = -1, ty0 = grid.tiles_y(), ty1 = -1;
    for (int ty = 0; ty < grid.tiles_y(); ++ty)
        for (int tx = 0; tx < grid.tiles_x(); ++tx)
            if (grid.tile_touched(tx, ty)) tx0 = std::min(tx0, tx), tx1 = std::max(tx1, tx), ty0 = std::min(ty0, ty), ty1 = std::max(ty1, ty);
    if (tx1 < 0) return {0, 0, 0, 0};
    const int T = SplatGrid::kTile;
    return {std::max(0, ty0 * T - reach), std::min(grid.rows(), (ty1 + 1) * T + reach),
            std::max(0, tx0 * T - reach), std::min(grid.columns(), (tx1 + 1) * T + reach)};
}

}  // namespace

void sharpen_nodes(SplatGrid& grid, double a, int distance, RenderControl& control) {
    if (a == 0.0) return;
    const NodeBox box = touched_box(grid, distance);
    if (box.r0 >= box.r1) return;
    const double centre = 1.0 + 2.0 * a;
    const int d = distance, width = box.c1 - box.c0;
    // Along rows: each row from a copy of itself with `d` zeros either side.
    tbb::parallel_for(box.r0, box.r1, [&](int r) {
        std::vector<double> copy(size_t(width + 2 * d), 0.0);
        double* row = grid.row(r) + box.c0;
        std::copy(row, row + width, copy.begin() + d);
        const double* in = copy.data() + d;
        for (int c = 0; c < width; ++c) row[c] = centre * in[c] - a * (in[c - d] + in[c + d]);
    });
    control.throw_if_cancelled();
    // Along columns, in strips of columns: each strip from a copy of its rows with `d` zero rows either side.
    constexpr int kStrip = 256;
    const int rows = box.r1 - box.r0;
    tbb::parallel_for(0, (width + kStrip - 1) / kStrip, [&](int strip) {
        const int c0 = box.c0 + strip * kStrip, w = std::min(kStrip, box.c1 - c0);
        std::vector<double> copy(size_t(rows + 2 * d) * w, 0.0);
        for (int r = 0; r < rows; ++r) std::copy(grid.row(box.r0 + r) + c0, grid.row(box.r0 + r) + c0 + w, copy.begin() + size_t(r + d) * w);
        for (int r = 0; r < rows; ++r) {
            const double *up = copy.data() + size_t(r) * w, *mid = up + size_t(d) * w, *down = mid + size_t(d) * w;
            double* out = grid.row(box.r0 + r) + c0;
            for (int c = 0; c < w; ++c) out[c] = centre * mid[c] - a * (up[c] + down[c]);
        }
    });
    control.throw_if_cancelled();
}

}  // namespace pcvr
