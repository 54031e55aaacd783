// Vector helpers (pcvr/lanes.h) and the post filters' properties (src/splat/post_convolution.h).
#include <algorithm>
#include <cmath>
#include <vector>

#include "pcvr/lanes.h"
#include "splat/post_convolution.h"
#include "splat/splat_grid.h"
#include "unit_test.h"

using namespace pcvr;

TEST(exp8_agrees_with_the_library_exp) {
    for (int i = -870; i <= 880; ++i) {  // its range: [-87, 88]
        const float x = i * 0.1f;
        const float8 lanes = exp8(broadcast8(x));
        CHECK_NEAR(lanes[3] / std::exp(x), 1.0, 1e-6);
    }
}

TEST(table_lookups_interpolate_each_lanes_two_entries) {
    std::vector<float> pairs(40), quads(4 * 40);
    for (size_t k = 0; k < pairs.size(); ++k) pairs[k] = float(k * k) * 0.5f;
    for (size_t k = 0; k < quads.size(); ++k) quads[k] = float((k * 7) % 13) - float(k) * 0.25f;
    const int8x i = {0, 38, 5, 5, 17, 2, 30, 11};
    const float8 f = {0.0f, 1.0f, 0.25f, 0.75f, 0.5f, 0.125f, 0.9f, 0.3f};
    const float8 p = lerp_pairs8(pairs.data(), i, f);
    float8 q[4];
    lerp_quads8(quads.data(), i, f, q);
    for (int l = 0; l < 8; ++l) {
        CHECK_NEAR(p[l], pairs[i[l]] + f[l] * (pairs[i[l] + 1] - pairs[i[l]]), 1e-5);
        for (int c = 0; c < 4; ++c) {
            const float a = quads[4 * i[l] + c], b = quads[4 * (i[l] + 1) + c];
            CHECK_NEAR(q[c][l], a + f[l] * (b - a), 1e-5);
        }
    }
}

TEST(bit_lookups_read_each_lanes_bit_of_the_word_it_falls_in) {
    // Words with their top bit set too: the shift must be logical.
    const std::vector<uint32_t> bits = {0x80000001u, 0x0000ff00u, 0xffffffffu, 0u};
    const int8x index = {0, 1, 31, 32 + 8, 32 + 16, 64 + 17, 96, 96 + 31};
    const int8x set = bit_set8(bits.data(), index);
    for (int l = 0; l < 8; ++l) {
        const bool expected = bits[size_t(index[l] >> 5)] >> (index[l] & 31) & 1u;
        CHECK(set[l] == (expected ? -1 : 0));
    }
}

TEST(post_filters_reach_and_overshoot) {
    for (int stride : {1, 3, 4, 8}) {
        CHECK(PostFilter(PostFilterShape::Bilinear, stride).reach_nodes() == 1);
        CHECK(PostFilter(PostFilterShape::Gauss14, stride).reach_nodes() == (stride == 1 ? 2 : 2));
        CHECK(PostFilter(PostFilterShape::Bilinear, stride).overshoot() == 0.0);
        CHECK(PostFilter(PostFilterShape::Gauss20, stride).overshoot() == 0.0);
    }
    // Catmull-Rom's negative lobes: halfway between nodes its taps are (-1, 9, 9, -1) / 16, negative 1/8
    // and positive 9/8 per axis, so 2 x 9/8 x 1/8 = 0.28 of negative weight in 2-D.
    const double catmull = PostFilter(PostFilterShape::CatmullRom, 8).overshoot();
    CHECK_NEAR(catmull, 0.28125, 1e-6);
    // It interpolates: a pixel on a node takes that node's value.
    const PostFilter f(PostFilterShape::CatmullRom, 4);
    CHECK(f.weights(0)[1] == 1.0f && f.weights(0)[0] == 0.0f && f.weights(0)[2] == 0.0f);
}

TEST(overshoot_is_the_largest_negative_weight_over_every_pixel_phase) {
    // Against every pair of phases: overshoot() takes the largest per phase instead, since fuzz_shaded
    // found that pairs at a fixed stride of 70000 (5e9 of them) hung the render in the culling setup.
    for (PostFilterShape shape : {PostFilterShape::Bilinear, PostFilterShape::Gauss14, PostFilterShape::CatmullRom})
        for (int stride : {1, 2, 3, 5, 8, 13}) {
            const PostFilter f(shape, stride);
            double most = 0;
            for (int px = 0; px < stride; ++px)
                for (int py = 0; py < stride; ++py) {
                    double negative = 0;
                    for (int i = 0; i < PostFilter::kTaps; ++i)
                        for (int j = 0; j < PostFilter::kTaps; ++j)
                            negative += std::max(0.0, -double(f.weights(px)[i]) * f.weights(py)[j]);
                    most = std::max(most, negative);
                }
            CHECK(f.overshoot() >= most - 1e-12);  // a bound (up to rounding), and a tight one
            CHECK_NEAR(f.overshoot(), most, 1e-6);
        }
    CHECK_NEAR(PostFilter(PostFilterShape::CatmullRom, 65536).overshoot(), 0.28125, 1e-6);
}

TEST(post_convolving_a_region_is_the_separable_filter) {
    const int L = 3, node_x0 = -4, node_y0 = -2, columns = 20, rows = 16;
    std::vector<float> nodes(size_t(columns) * rows);
    for (size_t i = 0; i < nodes.size(); ++i) nodes[i] = float((i * 7919) % 101) / 101.0f;
    for (PostFilterShape shape : {PostFilterShape::Bilinear, PostFilterShape::Gauss14, PostFilterShape::CatmullRom}) {
        const PostFilter f(shape, L);
        const int x0 = -5, y0 = 1, w = 31, h = 17;
        std::vector<float> out(size_t(w) * h), scratch;
        post_convolve_region({nodes.data(), size_t(columns), node_x0, node_y0}, f, x0, y0, w, h, out.data(), size_t(w), scratch);
        for (int y = y0; y < y0 + h; ++y)
            for (int x = x0; x < x0 + w; ++x) {
                const int nx = int(std::floor(double(x) / L)), ny = int(std::floor(double(y) / L));
                double sum = 0;
                for (int j = 0; j < 4; ++j)
                    for (int i = 0; i < 4; ++i)
                        sum += double(f.weights(y - ny * L)[j]) * f.weights(x - nx * L)[i] *
                               nodes[size_t(ny - 1 + j - node_y0) * columns + (nx - 1 + i - node_x0)];
                CHECK_NEAR(out[size_t(y - y0) * w + (x - x0)], sum, 1e-5);
            }
    }
}

TEST(post_filter_axis_at_whole_strides_is_the_post_filter) {
    for (PostFilterShape shape : {PostFilterShape::Bilinear, PostFilterShape::Gauss14, PostFilterShape::CatmullRom})
        for (int L : {1, 3, 4}) {
            const PostFilter f(shape, L);
            const PostFilterAxis axis(shape, double(L), 23);
            for (int x = 0; x < 23; ++x) {
                CHECK(axis.node(x) == x / L);
                for (int k = 0; k < PostFilter::kTaps; ++k) CHECK(axis.tap_weights(k)[x] == f.weights(x % L)[k]);
            }
            for (int n = 0; n <= 23 / L + 1; ++n) CHECK(axis.first_pixel(n) == std::min(23, n * L));
        }
}

TEST(post_filter_axis_at_fractional_strides) {
    // Nodes 2.2 pixels apart: pixel x reads nodes floor(x / 2.2) - 1 .. + 2 with the filter's weights
    // at its distance from each, normalised; node n's pixels are those whose node it is. Sampled at pixel
    // centres (render_xray's antialias=False):
    const double spacing = 2.2;
    const int pixels = 50;
    const PostFilterAxis axis(PostFilterShape::Bilinear, spacing, pixels, false);
    for (int x = 0; x < pixels; ++x) {
        const int n = int(std::floor(x / spacing));
        CHECK(axis.node(x) == n);
        CHECK(axis.first_pixel(n) <= x && x < axis.first_pixel(n + 1));
        const double t = x / spacing - n;  // bilinear: 1 - t on node n, t on node n + 1
        CHECK_NEAR(axis.tap_weights(1)[x], 1.0 - t, 1e-6);
        CHECK_NEAR(axis.tap_weights(2)[x], t, 1e-6);
        CHECK(axis.tap_weights(0)[x] == 0.0f && axis.tap_weights(3)[x] == 0.0f);
    }
    const PostFilterAxis gauss(PostFilterShape::Gauss14, spacing, pixels);
    for (int x = 0; x < pixels; ++x) {
        double sum = 0;
        for (int k = 0; k < PostFilter::kTaps; ++k) sum += gauss.tap_weights(k)[x];
        CHECK_NEAR(sum, 1.0, 1e-6);
    }
}

TEST(bilinear_averaged_over_pixels_conserves_every_nodes_mass) {
    // At fractional strides the bilinear filter is averaged over each pixel: a pixel's weights still add up
    // to one, and a node's over all pixels to its spacing, wherever it falls between pixels (point samples
    // at pixel centres miss that by up to a tenth at 1.5). Whole strides keep the point samples.
    for (double spacing : {1.125, 1.5, 2.2, 3.3, 5.7}) {
        const int pixels = 200;
        const PostFilterAxis axis(PostFilterShape::Bilinear, spacing, pixels);
        std::vector<double> node_sum(size_t(pixels), 0.0);
        for (int x = 0; x < pixels; ++x) {
            double row = 0;
            for (int k = 0; k < PostFilter::kTaps; ++k) {
                const float w = axis.tap_weights(k)[x];
                CHECK(w >= 0.0f);
                row += w;
                const int node = axis.node(x) - 1 + k;
                if (node >= 0) node_sum[size_t(node)] += w;
            }
            CHECK_NEAR(row, 1.0, 1e-6);
        }
        // Nodes whose every pixel is in the image: from node 2 to two nodes before the last pixel's.
        for (int n = 2; n + 2 <= axis.node(pixels - 1); ++n) CHECK_NEAR(node_sum[size_t(n)], spacing, 1e-5);
    }
    const PostFilterAxis whole(PostFilterShape::Bilinear, 3.0, 30), sampled(PostFilterShape::Bilinear, 3.0, 30, false);
    for (int x = 0; x < 30; ++x)
        for (int k = 0; k < PostFilter::kTaps; ++k) CHECK(whole.tap_weights(k)[x] == sampled.tap_weights(k)[x]);
}

TEST(post_filter_blur_is_the_mean_variance_of_the_weights) {
    // Bilinear at a whole stride L: t (1 - t) over the phases t = p / L, (1 - 1 / L^2) / 6; none at L = 1.
    for (int L = 1; L <= 8; ++L) CHECK_NEAR(post_filter_blur(PostFilterShape::Bilinear, L), (1.0 - 1.0 / (L * L)) / 6.0, 1e-6);
    // At fractional strides averaged over the pixels: the tent's 1/6 (less the phases' discreteness) plus a
    // pixel's box, 1 / (12 s^2) nodes^2; sampled at centres, no box.
    for (double s : {2.2, 3.3, 5.7}) {
        const double mean_phase = post_filter_blur(PostFilterShape::Bilinear, s, false);
        CHECK(mean_phase < 1.0 / 6.0 && mean_phase > (1.0 - 1.0 / (s * s)) / 6.0 - 0.02);
        CHECK_NEAR(post_filter_blur(PostFilterShape::Bilinear, s) - mean_phase, 1.0 / (12.0 * s * s), 2e-3);
    }
}

TEST(post_convolving_a_grid_at_a_fractional_stride_is_the_separable_filter) {
    const int width = 37, height = 29, margin = PostFilter::kMarginNodes;
    const double spacing = 2.7;
    SplatGrid grid(width, height, spacing, margin);
    for (int r = 0; r < grid.rows(); ++r)
        for (int c = 0; c < grid.columns(); ++c) grid.row(r)[c] = double((r * 31 + c * 17) % 13) / 13.0;
    grid.mark(0, 0, grid.columns() - 1, grid.rows() - 1);
    ImageAccumulator image(width, height);
    RenderControl control;
    post_convolve(grid, PostFilterShape::CatmullRom, image, control);
    const PostFilterAxis across(PostFilterShape::CatmullRom, spacing, width), down(PostFilterShape::CatmullRom, spacing, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            double sum = 0;
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i)
                    sum += double(down.tap_weights(j)[y]) * across.tap_weights(i)[x] *
                           grid.row(down.node(y) + margin - 1 + j)[across.node(x) + margin - 1 + i];
            CHECK_NEAR(image.pixels[size_t(y) * width + x], sum, 1e-5);
        }
}
