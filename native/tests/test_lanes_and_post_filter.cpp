// Vector helpers (pcvr/lanes.h) and the post filters' properties (pcvr/post_convolution.h).
#include <algorithm>
#include <cmath>
#include <vector>

#include "pcvr/lanes.h"
#include "pcvr/post_convolution.h"
#include "unit_test.h"

using namespace pcvr;

TEST(exp8_agrees_with_the_library_exp) {
    for (int i = -870; i <= 880; ++i) {  // its range: [-87, 88]
        const float x = i * 0.1f;
        const float8 lanes = exp8(broadcast8(x));
        CHECK_NEAR(lanes[3] / std::exp(x), 1.0, 1e-6);
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
