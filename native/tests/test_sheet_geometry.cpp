// Where perspective sheets lie (src/shaded/sheets/sheet_geometry.h): the metric in which a grid's voxels are
// cubes, and the frames of samples on spheres in that metric.
#include <cmath>
#include <vector>

#include "shaded/sheets/sheet_geometry.h"
#include "unit_test.h"

using namespace pcvr;

namespace {

/// A 320 x 240 camera at (0.3, -0.2, 5) looking down -z with a 50-degree vertical field of view.
Camera perspective_camera() {
    const double f = 1.0 / std::tan(25.0 * 3.14159265358979 / 180.0), aspect = 320.0 / 240.0, n = 0.1, far = 100.0;
    const Mat4 projection =
        Mat4::from_rows({f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + n) / (n - far), 2 * far * n / (n - far), 0, 0, -1, 0});
    return Camera(Mat4::from_rows({1, 0, 0, -0.3, 0, 1, 0, 0.2, 0, 0, 1, -5, 0, 0, 0, 1}), projection, 320, 240);
}

/// A CT's voxels, 0.5 x 0.5 x 1.2, turned about z by `angle` and scaled by `scale`.
Mat4 ct_voxels(double angle, double scale) {
    const double c = std::cos(angle) * scale, s = std::sin(angle) * scale;
    return Mat4::from_rows({0.5 * c, -0.5 * s, 0, 1, 0.5 * s, 0.5 * c, 0, 2, 0, 0, 1.2 * scale, 3, 0, 0, 0, 1});
}

Vec3 lane(const Vec3x8& v, int l) { return {v.x[l], v.y[l], v.z[l]}; }

}  // namespace

TEST(voxels_of_one_shape_are_cubes_in_their_sheet_metric) {
    // A CT and the same lattice turned and twice as coarse (its level 1) share a metric where both
    // are cubes, one twice the other's size; the metric keeps volumes.
    const Mat4 metric = sheet_metric({ct_voxels(0.0, 1.0), ct_voxels(0.4, 2.0)});
    const double fine = round_scale(metric, ct_voxels(0.0, 1.0)), coarse = round_scale(metric, ct_voxels(0.4, 2.0));
    CHECK(fine > 0 && coarse > 0);
    CHECK_NEAR(coarse / fine, 2.0, 1e-9);
    CHECK_NEAR(fine, std::cbrt(0.5 * 0.5 * 1.2), 1e-9);
    // Cubic voxels, turned or not: exactly the world's own metric (whose inverse scaled to keep
    // volumes is the identity only to rounding).
    const Mat4 turned = ct_voxels(0.7, 1.0) * Mat4::from_rows({1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0.5 / 1.2, 0, 0, 0, 0, 1});
    for (const Mat4& cubic : {Mat4::from_rows({0.1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 0.1, 0, 0, 0, 0, 1}), turned})
        CHECK(is_identity(sheet_metric({cubic})));
}

TEST(voxels_of_different_shapes_keep_the_worlds_metric) {
    const Mat4 metric = sheet_metric({ct_voxels(0.0, 1.0), Mat4::identity()});
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) CHECK(metric.m[i][j] == (i == j ? 1.0 : 0.0));
    CHECK(round_scale(metric, ct_voxels(0.0, 1.0)) == 0.0);
    CHECK(round_scale(metric, Mat4::identity()) == 1.0);
}

TEST(samples_lie_on_spheres_of_the_metric_and_their_frames_are_the_derivatives) {
    const Camera cam = perspective_camera();
    SheetGeometry geo(cam);
    const Mat4 metric = sheet_metric({ct_voxels(0.3, 1.0)});
    geo.use_metric(metric, cam);
    const double u = 4.7;
    const float py = 37.0f;
    const float8 px = float8{3, 50, 100, 151, 200, 250, 290, 319};
    const SampleFrames f = sample_frames(geo, true, px, py, u);
    // Central differences: half a pixel, a hundredth of the parameter (second-order errors ~1e-4).
    const float h = 0.5f;
    const double k = 0.01;
    const SampleFrames left = sample_frames(geo, true, px - h, py, u), right = sample_frames(geo, true, px + h, py, u);
    const SampleFrames up = sample_frames(geo, true, px, py - h, u), down = sample_frames(geo, true, px, py + h, u);
    const SampleFrames before = sample_frames(geo, true, px, py, u - k), beyond = sample_frames(geo, true, px, py, u + k);
    auto derivative = [](const Vec3x8& a, const Vec3x8& b, int l, double step) { return (lane(b, l) - lane(a, l)) * (0.5 / step); };
    for (int l = 0; l < 8; ++l) {
        const Vec3 p = lane(f.position, l);  // relative to the eye
        CHECK_NEAR(length(metric.transform_vector(p)), u, 1e-5);
        // On the pixel's ray, at the depth the frame says.
        const Vec3 ray = geo.direction(px[l], py) * double(f.depth[l]);
        CHECK_NEAR(length(ray - p), 0.0, 1e-5);
        // Per pixel and per unit of the sheet parameter: the frame is the positions' derivative.
        const Vec3 dx = derivative(left.position, right.position, l, h), dy = derivative(up.position, down.position, l, h);
        const Vec3 du = derivative(before.position, beyond.position, l, k);
        CHECK_NEAR(length(dx - lane(f.per_pixel_x, l)), 0.0, 1e-3 * length(lane(f.per_pixel_x, l)));
        CHECK_NEAR(length(dy - lane(f.per_pixel_y, l)), 0.0, 1e-3 * length(lane(f.per_pixel_y, l)));
        CHECK_NEAR(length(du - lane(f.along, l)), 0.0, 1e-3 * length(lane(f.along, l)));
        CHECK_NEAR(double(f.depth_rate[l]) * u, double(f.depth[l]), 1e-5);
    }
}
