#include "splat/post_convolution.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "pcvr/errors.h"

namespace pcvr {

PostFilterShape post_filter_from_name(const std::string& name) {
    if (name == "bilinear") return PostFilterShape::Bilinear;
    if (name == "gauss1.4") return PostFilterShape::Gauss14;
    if (name == "gauss2.0") return PostFilterShape::Gauss20;
    if (name == "catmull_rom") return PostFilterShape::CatmullRom;
    throw InvalidArgument("unknown post filter '" + name + "' (expected bilinear, gauss1.4, gauss2.0 or catmull_rom)");
}

namespace {

/// The filter's 1-D weight of a node `t` nodes from a pixel.
double post_weight(PostFilterShape shape, double t) {
    t = std::abs(t);
    switch (shape) {
        case PostFilterShape::Bilinear: return t < 1.0 ? 1.0 - t : 0.0;
        case PostFilterShape::Gauss14: return t < 2.0 ? std::exp(-1.4 * t * t) : 0.0;
        case PostFilterShape::Gauss20: return t < 2.0 ? std::exp(-2.0 * t * t) : 0.0;
        case PostFilterShape::CatmullRom:  // the cubic that interpolates with the slopes of central differences
            return t < 1.0 ? 1.5 * t * t * t - 2.5 * t * t + 1.0 : (t < 2.0 ? -0.5 * t * t * t + 2.5 * t * t - 4.0 * t + 2.0 : 0.0);
    }
    return 0.0;
}

/// Weights of nodes base - 1 .. base + 2 for a pixel `fraction` of a node right of node base,
/// normalised so that a constant stays constant.
void normalised_weights(PostFilterShape shape, double fraction, float out[PostFilter::kTaps]) {
    double w[PostFilter::kTaps], sum = 0;
    for (int k = 0; k < PostFilter::kTaps; ++k) {
        // Node base - 1 + k lies (1 - k) nodes plus the fraction left of the pixel.
        w[k] = post_weight(shape, fraction + 1.0 - k);
        sum += w[k];
    }
    for (int k = 0; k < PostFilter::kTaps; ++k) out[k] = float(w[k] / sum);
}

}  // namespace

PostFilter::PostFilter(PostFilterShape shape, int stride) : stride_(stride), weights_(size_t(stride) * kTaps) {
    for (int phase = 0; phase < stride; ++phase) normalised_weights(shape, double(phase) / stride, &weights_[size_t(phase) * kTaps]);
    by_tap_.resize(weights_.size());
    for (int phase = 0; phase < stride; ++phase)
        for (int k = 0; k < kTaps; ++k) by_tap_[size_t(k) * stride + phase] = weights_[size_t(phase) * kTaps + k];
}

namespace {

/// Integral of the tent 1 - |u| from -infinity to u.
double tent_integral(double u) {
    if (u <= -1.0) return 0.0;
    if (u <= 0.0) return 0.5 * (u + 1.0) * (u + 1.0);
    if (u < 1.0) return 1.0 - 0.5 * (1.0 - u) * (1.0 - u);
    return 1.0;
}

/// The bilinear weights of nodes base - 1 .. base + 2 averaged over a pixel centred `fraction` of a node
/// right of node base and `width` nodes wide (at most 1): the linear interpolant's mean over the pixel.
void pixel_mean_bilinear(double fraction, double width, float out[PostFilter::kTaps]) {
    const double lo = fraction - 0.5 * width, hi = fraction + 0.5 * width;
    for (int k = 0; k < PostFilter::kTaps; ++k) {
        const double node = k - 1.0;
        out[k] = float((tent_integral(hi - node) - tent_integral(lo - node)) / width);
    }
}

/// Whether nodes `spacing` pixels apart fall on whole pixels (PostFilter's phases).
bool whole_spacing(double spacing) { return spacing == std::floor(spacing); }

/// One pixel's weights along an axis of nodes `spacing` pixels apart, and the node at or before it.
int axis_weights(PostFilterShape shape, double spacing, bool pixel_mean, int x, float w[PostFilter::kTaps]) {
    const double n = std::floor(x / spacing);
    // x - n * spacing is the whole phase for whole spacings, so they get PostFilter's weights exactly;
    // otherwise it may round to just below zero, where the outer taps would get a sliver of weight.
    const double fraction = std::clamp((x - n * spacing) / spacing, 0.0, 1.0);
    // Sampled at pixel centres, the interpolant gives each node's pixels a total weight that depends on
    // where the node falls between pixels: a stride of 1.125 lost up to 7% of a column's mass seen end-on.
    // Averaged over each pixel's area, the node's weights add up to its spacing wherever it falls (the
    // pixels tile the line), at the cost of a pixel's box (1/12 px^2), which the passband compensation
    // pays back. Whole spacings keep the point samples, which already conserve mass.
    if (pixel_mean && shape == PostFilterShape::Bilinear && !whole_spacing(spacing))
        pixel_mean_bilinear(fraction, 1.0 / spacing, w);
    else
        normalised_weights(shape, fraction, w);
    return int(n);
}

}  // namespace

PostFilterAxis::PostFilterAxis(PostFilterShape shape, double spacing, int pixels, bool pixel_mean) : node_(size_t(pixels)) {
    for (auto& w : by_tap_) w.resize(size_t(pixels));
    for (int x = 0; x < pixels; ++x) {
        float w[PostFilter::kTaps];
        node_[size_t(x)] = axis_weights(shape, spacing, pixel_mean, x, w);
        for (int k = 0; k < PostFilter::kTaps; ++k) by_tap_[k][size_t(x)] = w[k];
    }
    const int nodes = pixels > 0 ? node_.back() + 1 : 0;
    first_pixel_.assign(size_t(nodes) + 1, pixels);
    for (int x = pixels - 1; x >= 0; --x) first_pixel_[size_t(node_[size_t(x)])] = x;
    for (int n = nodes - 1; n >= 0; --n) first_pixel_[size_t(n)] = std::min(first_pixel_[size_t(n)], first_pixel_[size_t(n) + 1]);
}

double post_filter_blur(PostFilterShape shape, double spacing, bool pixel_mean) {
    // A whole spacing repeats after `spacing` pixels; a fractional one is averaged over enough of them.
    const int pixels = whole_spacing(spacing) ? int(spacing) : std::max(256, int(std::ceil(64 * spacing)));
    double sum = 0;
    for (int x = 0; x < pixels; ++x) {
        float w[PostFilter::kTaps];
        const int n = axis_weights(shape, spacing, pixel_mean, x, w);
        const double centre = x / spacing;  // in nodes
        double mean = 0, second = 0;
        for (int k = 0; k < PostFilter::kTaps; ++k) {
            const double offset = n - 1 + k - centre;
            mean += w[k] * offset;
            second += w[k] * offset * offset;
        }
        sum += second - mean * mean;
    }
    return sum / pixels;
}

int PostFilter::reach_nodes() const {
    for (int phase = 0; phase < stride_; ++phase)
        if (weights(phase)[0] != 0 || weights(phase)[3] != 0) return 2;
    return 1;
}

double PostFilter::overshoot() const {
    // The negative weights of pixel phase (px, py) add up to P(px) N(py) + N(px) P(py), with P and N a
    // phase's positive and negative weights: at most 2 max P max N, which the phase with the largest
    // N reaches (P = 1 + N). Per phase, not per pair: strides reach 65536.
    double most_positive = 0, most_negative = 0;
    for (int phase = 0; phase < stride_; ++phase) {
        double positive = 0, negative = 0;
        for (int k = 0; k < kTaps; ++k) (weights(phase)[k] > 0 ? positive : negative) += std::abs(double(weights(phase)[k]));
        most_positive = std::max(most_positive, positive);
        most_negative = std::max(most_negative, negative);
    }
    return 2.0 * most_positive * most_negative;
}

namespace {

int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/// Pixels L n + p, p in [p0, p1), of node n's run, from the horizontal neighbours n - 1 .. n + 2 at
/// `sums`; out points at the pixel of phase 0. One contiguous loop over the phases.
inline void node_run(const PostFilter& filter, const float* sums, int p0, int p1, float* out) {
    const float *w0 = filter.tap_weights(0), *w1 = filter.tap_weights(1), *w2 = filter.tap_weights(2),
                *w3 = filter.tap_weights(3);
    const float n0 = sums[-1], n1 = sums[0], n2 = sums[1], n3 = sums[2];
    for (int p = p0; p < p1; ++p) out[p] = w0[p] * n0 + w1[p] * n1 + w2[p] * n2 + w3[p] * n3;
}

/// node_run for the whole runs of nodes n0 .. n1 at a stride L known when compiling: the phases unrolled,
/// one loop over the nodes (node_run's loop of L pixels per node was most of the horizontal pass at the
/// small strides sampled sheets take).
template <int L>
void whole_node_runs(const PostFilter& filter, const float* node_row, int n0, int n1, float* h) {
    float w[PostFilter::kTaps][L];
    for (int k = 0; k < PostFilter::kTaps; ++k)
        for (int p = 0; p < L; ++p) w[k][p] = filter.tap_weights(k)[p];
    for (int n = n0; n <= n1; ++n) {
        const float a = node_row[n - 1], b = node_row[n], c = node_row[n + 1], d = node_row[n + 2];
        float* out = h + L * n;
        for (int p = 0; p < L; ++p) out[p] = w[0][p] * a + w[1][p] * b + w[2][p] * c + w[3][p] * d;
    }
}

/// Pixels [x0, x0 + width) of one node row's horizontal pass into h (by image column).
void horizontal_pass(const PostFilter& filter, const float* node_row, int x0, int width, float* h) {
    const int L = filter.stride();
    const int first_column = floor_div(x0, L), last_column = floor_div(x0 + width - 1, L);
    auto partial = [&](int n) {
        const int p0 = std::max(0, x0 - n * L), p1 = std::min(L, x0 + width - n * L);
        node_run(filter, node_row + n, p0, p1, h + n * L);
    };
    // The first and last nodes may have only some of their phases in the region.
    const int inner0 = first_column + 1, inner1 = last_column - 1;
    if (L > 4 || inner0 > inner1) {
        for (int n = first_column; n <= last_column; ++n) partial(n);
        return;
    }
    partial(first_column);
    switch (L) {
        case 1: whole_node_runs<1>(filter, node_row, inner0, inner1, h); break;
        case 2: whole_node_runs<2>(filter, node_row, inner0, inner1, h); break;
        case 3: whole_node_runs<3>(filter, node_row, inner0, inner1, h); break;
        default: whole_node_runs<4>(filter, node_row, inner0, inner1, h); break;
    }
    partial(last_column);
}

}  // namespace

void post_convolve(const SplatGrid& grid, PostFilterShape shape, ImageAccumulator& image, RenderControl& control,
                   bool pixel_mean) {
    const PostFilterAxis across(shape, grid.stride(), image.width, pixel_mean), down(shape, grid.stride(), image.height, pixel_mean);
    const float *wx0 = across.tap_weights(0), *wx1 = across.tap_weights(1), *wx2 = across.tap_weights(2),
                *wx3 = across.tap_weights(3);
    const int T = SplatGrid::kTile;
    // Storage column of the node at or left of pixel x is across.node(x) - first_node_x; its taps are
    // one left and two right of it, so output tile t needs node tiles t - 1 .. t + 1.
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

        const int y_lo = down.first_pixel(ty * T - sy0), y_hi = down.first_pixel((ty + 1) * T - sy0);
        for (int y = y_lo; y < y_hi; ++y) {
            // At large strides one tile row spans thousands of pixel rows: stop between them.
            control.throw_if_cancelled();
            // Vertical pass: the four node rows around this pixel row, for the needed columns.
            const float wy[PostFilter::kTaps] = {down.tap_weights(0)[y], down.tap_weights(1)[y], down.tap_weights(2)[y],
                                                 down.tap_weights(3)[y]};
            const double* r[PostFilter::kTaps];
            for (int k = 0; k < PostFilter::kTaps; ++k) r[k] = grid.row(down.node(y) + sy0 - 1 + k);
            for (int c = col_lo; c <= col_hi; ++c)
                column_sums[c] = float(wy[0] * r[0][c] + wy[1] * r[1][c] + wy[2] * r[2][c] + wy[3] * r[3][c]);

            // Horizontal pass over the active tiles: each node's run of pixels is one contiguous,
            // vectorisable loop over their weights.
            float* out = image.pixels.data() + size_t(y) * image.width;
            for (int tx = first; tx <= last; ++tx) {
                if (!active[tx]) continue;
                for (int sc = std::max(tx * T, sx0); sc < (tx + 1) * T; ++sc) {
                    const int x0 = across.first_pixel(sc - sx0), x1 = across.first_pixel(sc - sx0 + 1);
                    if (x0 >= image.width) break;
                    const float n0 = column_sums[sc - 1], n1 = column_sums[sc], n2 = column_sums[sc + 1], n3 = column_sums[sc + 2];
                    for (int x = x0; x < x1; ++x) out[x] += wx0[x] * n0 + wx1[x] * n1 + wx2[x] * n2 + wx3[x] * n3;
                }
            }
        }
    });
    control.throw_if_cancelled();
}

void post_convolve_region(const NodeSheet& nodes, const PostFilter& filter, int x0, int y0, int width, int height,
                          float* out, size_t out_pitch, std::vector<float>& scratch, bool add) {
    // Horizontally first, once per node row, into full-width rows; then every pixel row is a weighted
    // sum of (at most) four of those rows: long loops over the row that vectorise, where the vertical
    // pass of a node run would be a loop of only L pixels per output row.
    const int L = filter.stride();
    const int first_row = floor_div(y0, L) - 1, last_row = floor_div(y0 + height - 1, L) + 2;
    const size_t row_floats = size_t(width);
    scratch.resize(row_floats * size_t(last_row - first_row + 1));
    // Taps that carry no weight at any phase (the bilinear filter's outer two) are left out.
    const int outer = filter.reach_nodes() == 2 ? 0 : 1;
    for (int r = first_row; r <= last_row; ++r) {
        const float* node_row = nodes.values + size_t(r - nodes.node_y0) * nodes.pitch - nodes.node_x0;  // by subgrid column
        float* h = scratch.data() + size_t(r - first_row) * row_floats - x0;                            // by image column
        horizontal_pass(filter, node_row, x0, width, h);
    }
    for (int y = y0; y < y0 + height; ++y) {
        const int node = floor_div(y, L), phase = y - node * L;
        const float* wy = filter.weights(phase);
        const float* h[PostFilter::kTaps];
        for (int k = 0; k < PostFilter::kTaps; ++k) h[k] = scratch.data() + size_t(node - 1 + k - first_row) * row_floats;
        float* row = out + size_t(y - y0) * out_pitch;
        auto combine = [&](auto value) {  // stored or added: each a plain loop that vectorises
            if (add)
                for (int x = 0; x < width; ++x) row[x] += value(x);
            else
                for (int x = 0; x < width; ++x) row[x] = value(x);
        };
        if (outer) {
            const float a = wy[1], b = wy[2];
            combine([&](int x) { return a * h[1][x] + b * h[2][x]; });
        } else {
            const float a = wy[0], b = wy[1], c = wy[2], d = wy[3];
            combine([&](int x) { return a * h[0][x] + b * h[1][x] + c * h[2][x] + d * h[3][x]; });
        }
    }
}

void add_unfiltered(const SplatGrid& grid, ImageAccumulator& image) {
    for (int y = 0; y < image.height; ++y) {
        const double* src = grid.row(y - grid.first_node_y()) - grid.first_node_x();
        float* dst = image.pixels.data() + size_t(y) * image.width;
        for (int x = 0; x < image.width; ++x) dst[x] += float(src[x]);
    }
}

}  // namespace pcvr
