#include "pcvr/post_convolution.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "pcvr/errors.h"

namespace pcvr {

PostFilterShape post_filter_from_name(const std::string& name) {
    if (name == "bilinear") return PostFilterShape::Bilinear;
    if (name == "gauss1.4") return PostFilterShape::Gauss14;
    if (name == "gauss2.0") return PostFilterShape::Gauss20;
    throw InvalidArgument("unknown post filter '" + name + "' (expected bilinear, gauss1.4 or gauss2.0)");
}

PostFilter::PostFilter(PostFilterShape shape, int stride) : stride_(stride), weights_(size_t(stride) * kTaps) {
    auto weight = [shape](double t) {
        t = std::abs(t);
        switch (shape) {
            case PostFilterShape::Bilinear: return t < 1.0 ? 1.0 - t : 0.0;
            case PostFilterShape::Gauss14: return t < 2.0 ? std::exp(-1.4 * t * t) : 0.0;
            case PostFilterShape::Gauss20: return t < 2.0 ? std::exp(-2.0 * t * t) : 0.0;
        }
        return 0.0;
    };
    for (int phase = 0; phase < stride; ++phase) {
        double w[kTaps], sum = 0;
        for (int k = 0; k < kTaps; ++k) {
            // Node base - 1 + k lies (1 - k) nodes plus the phase fraction left of the pixel.
            w[k] = weight(double(phase) / stride + 1.0 - k);
            sum += w[k];
        }
        for (int k = 0; k < kTaps; ++k) weights_[size_t(phase) * kTaps + k] = float(w[k] / sum);
    }
    by_tap_.resize(weights_.size());
    for (int phase = 0; phase < stride; ++phase)
        for (int k = 0; k < kTaps; ++k) by_tap_[size_t(k) * stride + phase] = weights_[size_t(phase) * kTaps + k];
}

void post_convolve(const SplatGrid& grid, const PostFilter& filter, ImageAccumulator& image, RenderControl& control) {
    const int L = filter.stride();
    const int T = SplatGrid::kTile;
    // Storage column of the node at or left of pixel x is x / L - first_node_x; its taps are one
    // left and two right of it, so output tile t needs node tiles t - 1 .. t + 1.
    const int sx0 = -grid.first_node_x(), sy0 = -grid.first_node_y();
    auto touched_near = [&](int tx, int ty) {
        for (int y = std::max(0, ty - 1); y <= std::min(grid.tiles_y() - 1, ty + 1); ++y)
            for (int x = std::max(0, tx - 1); x <= std::min(grid.tiles_x() - 1, tx + 1); ++x)
                if (grid.tile_touched(x, y)) return true;
        return false;
    };

    tbb::parallel_for(0, grid.tiles_y(), [&](int ty) {
        control.throw_if_cancelled();
        std::vector<char> active(grid.tiles_x());
        int first = grid.tiles_x(), last = -1;
        for (int tx = 0; tx < grid.tiles_x(); ++tx) {
            active[tx] = touched_near(tx, ty);
            if (active[tx]) first = std::min(first, tx), last = tx;
        }
        if (last < 0) return;
        const int col_lo = std::max(0, first * T - 1), col_hi = std::min(grid.columns() - 1, (last + 1) * T + 1);
        std::vector<float> column_sums(grid.columns(), 0.0f);
        const float *w0 = filter.tap_weights(0), *w1 = filter.tap_weights(1), *w2 = filter.tap_weights(2),
                    *w3 = filter.tap_weights(3);

        const int y_lo = std::max(0, (ty * T - sy0) * L), y_hi = std::min(image.height - 1, ((ty + 1) * T - sy0) * L - 1);
        for (int y = y_lo; y <= y_hi; ++y) {
            // At large strides one tile row spans thousands of pixel rows: stop between them.
            control.throw_if_cancelled();
            // Vertical pass: the four node rows around this pixel row, for the needed columns.
            const int node = y / L, phase = y - node * L;
            const float* wy = filter.weights(phase);
            const double* r[PostFilter::kTaps];
            for (int k = 0; k < PostFilter::kTaps; ++k) r[k] = grid.row(node + sy0 - 1 + k);
            for (int c = col_lo; c <= col_hi; ++c)
                column_sums[c] = float(wy[0] * r[0][c] + wy[1] * r[1][c] + wy[2] * r[2][c] + wy[3] * r[3][c]);

            // Horizontal pass over the active tiles: each node's run of L pixels is one contiguous,
            // vectorisable loop over the phases.
            float* out = image.pixels.data() + size_t(y) * image.width;
            for (int tx = first; tx <= last; ++tx) {
                if (!active[tx]) continue;
                for (int sc = std::max(tx * T, sx0); sc < (tx + 1) * T; ++sc) {
                    const int x_base = (sc - sx0) * L;
                    if (x_base >= image.width) break;
                    const float n0 = column_sums[sc - 1], n1 = column_sums[sc], n2 = column_sums[sc + 1],
                                n3 = column_sums[sc + 2];
                    float* o = out + x_base;
                    const int run = std::min(L, image.width - x_base);
                    for (int p = 0; p < run; ++p) o[p] += w0[p] * n0 + w1[p] * n1 + w2[p] * n2 + w3[p] * n3;
                }
            }
        }
    });
    control.throw_if_cancelled();
}

void add_unfiltered(const SplatGrid& grid, ImageAccumulator& image) {
    for (int y = 0; y < image.height; ++y) {
        const double* src = grid.row(y - grid.first_node_y()) - grid.first_node_x();
        float* dst = image.pixels.data() + size_t(y) * image.width;
        for (int x = 0; x < image.width; ++x) dst[x] += float(src[x]);
    }
}

}  // namespace pcvr
