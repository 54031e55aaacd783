// A perspective view's footprints linearised per voxel block (src/splat/block_linearisation.h): the
// model every voxel of a linearised block takes its footprint from, against the exact projection.
#include <algorithm>
#include <cmath>

#include "splat/block_linearisation.h"
#include "unit_test.h"

using namespace pcvr;

namespace {

constexpr double kVariance = 0.357;  // gauss1.4's per-axis variance (index units^2)

/// A 512 x 384 camera at the origin looking down -z with a 40-degree vertical field of view.
Camera perspective_camera() {
    const double f = 1.0 / std::tan(20.0 * 3.14159265358979 / 180.0), aspect = 512.0 / 384.0, n = 0.1, far = 1000.0;
    Mat4 projection = Mat4::from_rows({f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + n) / (n - far), 2 * far * n / (n - far), 0, 0, -1, 0});
    return Camera(Mat4::identity(), projection, 512, 384);
}

/// Index space: voxels of 0.01 world units, index (0, 0, 0) at `corner`.
Mat4 voxels_at(double x, double y, double z) {
    return Mat4::from_rows({0.01, 0, 0, x, 0, 0.01, 0, y, 0, 0, 0.01, z, 0, 0, 0, 1});
}

VoxelBlock block_at(int i, int j, int k) {
    VoxelBlock b;
    b.origin = {i, j, k};
    return b;
}

/// The model's largest errors over the block's 512 voxels: node position (nodes) and form
/// (relative to the exact form's mean eigenvalue).
struct ModelError {
    double position = 0, form = 0, line_scale = 0;
};

ModelError model_error(const BlockLinearisation& lin, const VoxelBlock& block, const ViewProjection& view, const SplatGrid& grid) {
    auto at = [](const AffineInBlock& f, int i, int j, int k) { return double(f.at) + f.di * i + f.dj * j + f.dk * k; };
    const double s2 = grid.stride() * grid.stride();
    ModelError e;
    for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j)
            for (int k = 0; k < 8; ++k) {
                Footprint f;
                CHECK(view.footprint({double(block.origin[0] + i), double(block.origin[1] + j), double(block.origin[2] + k)}, f));
                const double w = at(lin.w, i, j, k);
                e.position = std::max({e.position, std::abs(at(lin.x, i, j, k) / w - grid.node_x(f.px)),
                                       std::abs(at(lin.y, i, j, k) / w - grid.node_y(f.py))});
                const double scale = 0.5 * (f.qxx + f.qyy) * s2;
                e.form = std::max({e.form, std::abs(at(lin.qxx, i, j, k) - f.qxx * s2) / scale,
                                   std::abs(at(lin.qxy, i, j, k) - f.qxy * s2) / scale, std::abs(at(lin.qyy, i, j, k) - f.qyy * s2) / scale});
                e.line_scale = std::max(e.line_scale, std::abs(at(lin.line_scale, i, j, k) / f.line_scale - 1.0));
            }
    return e;
}

}  // namespace

TEST(linearised_block_footprints_match_the_exact_projection) {
    // 40 voxels from the eye's plane off the axis: the model's remainder is within its tolerance
    // at every voxel, not only at the corners it was checked at, and centres are exact to float.
    const Camera cam = perspective_camera();
    const ViewProjection view(cam, voxels_at(-0.3, 0.2, -4.0));
    const SplatGrid grid(cam.width(), cam.height(), 2.5, 2);
    const VoxelBlock block = block_at(8, -16, -8);
    const auto lin = linearise_block(block, view, grid, 0, 0, true, kVariance);
    CHECK(lin.has_value());
    if (!lin) return;
    const ModelError e = model_error(*lin, block, view, grid);
    CHECK(e.position < 2e-3);
    CHECK(e.form < kLinearisedTolerance);
    CHECK(e.line_scale < kLinearisedTolerance);
}

TEST(blocks_near_the_eye_keep_exact_footprints) {
    // A block 6 voxels from the eye: its footprints change by a third across it.
    const Camera cam = perspective_camera();
    const ViewProjection view(cam, voxels_at(-0.04, -0.04, -0.1));
    const SplatGrid grid(cam.width(), cam.height(), 4.0, 2);
    CHECK(!linearise_block(block_at(0, 0, -8), view, grid, 0, 0, true, kVariance).has_value());
}

TEST(blocks_narrower_than_a_pixel_are_linearised_as_prefiltered) {
    // Far away every footprint of the block is narrower than a pixel: prefiltered, unless
    // antialiasing is off; the model holds there too.
    const Camera cam = perspective_camera();
    const ViewProjection far(cam, voxels_at(0.0, 0.0, -40.0));
    const SplatGrid grid(cam.width(), cam.height(), 1.0, 2);
    const VoxelBlock block = block_at(0, 0, 0);
    const auto lin = linearise_block(block, far, grid, 0, 0, true, kVariance);
    CHECK(lin.has_value() && lin->prefiltered);
    const auto sampled = linearise_block(block, far, grid, 0, 0, false, kVariance);
    CHECK(sampled.has_value() && !sampled->prefiltered);
    if (lin) CHECK(model_error(*lin, block, far, grid).form < kLinearisedTolerance);
    // A block whose voxels span a pixel at one end and less at the other is linearised too, all its
    // footprints sampled or all prefiltered as its centre is (block_prefiltered): a voxel of 0.01 units
    // spans 1 pixel at 384 / (2 tan 20 deg) / 100 = 5.275 units from the eye, and the block's voxels lie
    // 5.23 to 5.30 (5.25 to 5.32) units away.
    for (double depth : {5.30, 5.32}) {
        const ViewProjection straddling(cam, voxels_at(-0.035, -0.035, -depth));
        const auto both = linearise_block(block_at(0, 0, 0), straddling, grid, 0, 0, true, kVariance);
        CHECK(both.has_value());
        if (both) CHECK(both->prefiltered == block_prefiltered(block_at(0, 0, 0), straddling));
    }
    // The centre lies 5.265 units away (sampled) at the first depth, 5.285 (averaged) at the second.
    CHECK(!block_prefiltered(block_at(0, 0, 0), ViewProjection(cam, voxels_at(-0.035, -0.035, -5.30))));
    CHECK(block_prefiltered(block_at(0, 0, 0), ViewProjection(cam, voxels_at(-0.035, -0.035, -5.32))));
}
