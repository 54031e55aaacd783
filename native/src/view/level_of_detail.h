/// @file level_of_detail.h
/// @brief Which level of detail (Grid::level) an X-ray renders a grid from, what its footprints are, and
/// when a zoomed-out view renders supersampled.
///
/// A zoomed-out view need not visit every voxel: level k has 8^k times fewer, each the mean of the
/// 2^k x 2^k x 2^k voxels it stands for, placed at their centroid. Its voxels are splatted with the
/// footprint of what they stand for, not of one coarse kernel: 8^k kernels of variance v (index
/// units of level 0) spread uniformly over 2^k voxels each way add the box's variance (4^k - 1) / 12,
/// so a level-k voxel's footprint has the variance of the fine voxels it replaces and nothing more
/// (with level k's own kernel, variance v 4^k, the image blurred by about a coarse voxel: 1.7% off
/// the pixel means at level 1 and magnification 1/16 on the tests' 48^3 blobs, against 0.7% this
/// way). What remains is that a coarse voxel puts its mass at its centre, not where in it the mass
/// was, and that the levels resample the volume: detail at the scale of a coarse voxel is averaged
/// away, whatever the pixels. Relative RMSE against pixel means, pcvr (level 0: 0.01-0.16%):
///
/// | magnification | level 1 | level 2 | level 3 | (48^3 blobs; 128^3 blobs of 8-13 voxels)   |
/// |---------------|---------|---------|---------|--------------------------------------------|
/// | 1/128         | 0.01%   | 0.03%   | 0.21%   |                                            |
/// | 1/64          | 0.08%   | 0.37%   | 1.4%    | 0.06%, 0.26%, 1.0%                          |
/// | 1/32          | 0.65%   | 2.8%    | 10%     |                                            |
/// | 1/16          | 0.73%   | 3.1%    | 11%     | 0.21%, 0.89%, 3.5%                          |
/// | 1/8           | 1.2%    | 5.0%    | 29%     | 0.24%, 1.05%, 7.9%                          |
///
/// So automatic levels keep coarse voxels at most 1/32 of a pixel wide, which held the error under
/// 0.1% in every case measured (1/16 gave 0.65% at 1/32); `level=k` trades accuracy for speed beyond that (the viewport's
/// coarse first images). Measured again with a reference of 2 x the sub-pixels (the tests' 8 x 8 or one a voxel
/// is itself 0.01-0.14% off a finer one), level 1 at 1/64 is 0.08% (blobs) and 0.17% (64^3 CT phantom) off.
///
/// Supersampling. Below a pixel per voxel every footprint is integrated over its pixels
/// (splat/pixel_prefilter.h), 5 to 8 times the work of a voxel splatted at magnification 1 (128^3 blobs:
/// 65-97 ms at 1/4 to 1/32, 9-14 ms at m = 1, one core). Where every voxel of an automatic level 0 projects to
/// at most 1/2 pixel in an orthographic view, the image is rendered at s x s sub-pixels a pixel instead, s the
/// fewest that give every voxel a sub-pixel, and box-averaged: the pixel means by the midpoint rule, one sample
/// a voxel. Relative RMSE against pixel means of 3 x max(8, 1/m) sub-pixels, 48^3 blobs / 64^3 CT phantom:
///
/// | magnification | supersampled (s)         | integrated per pixel | 128^3 ms, supersampled / integrated |
/// |---------------|--------------------------|----------------------|-------------------------------------|
/// | 1/4           | 0.21% / 0.33% (4)        | 0.004% / 0.006%      | (not taken)                         |
/// | 1/8           | 0.14% / 0.14% (8)        | 0.018% / 0.014%      |                                     |
/// | 1/16          | 0.10% / 0.05% (16)       | 0.011% / 0.006%      | blobs 10-14 / 66-97, CT 8.5-9.4 / 52-77 |
/// | 1/32          | 0.08% / 0.02% (32)       | 0.010% / 0.003%      |                                     |
///
/// Ten times the error of integrating, within the 0.5% asked, at the cost of magnification 1. At 1/2 and 1/4
/// the pixel means of the kernel model are missed by more (blobs 0.30 / 0.25%, CT phantom 0.71 / 0.33%, with
/// the paper's passband), but what counts is the volume's own line integrals: against the analytic pixel means
/// of the 128^3 blobs (sampled Gaussians, tests/native/test_xray_levels.py), with the default compensated
/// passband, supersampled 0.36% (1/2) and 0.28% (1/4), integrated per pixel 0.13% and 0.29%, the paper's pair
/// integrated 1.26% and 1.15%; so the threshold is 1/2, where one core took 13.5 ms supersampled against 110 ms
/// integrated (m = 1: 13.9 ms). Wide perspective views
/// gained 12% at most (the near voxels span many sub-pixels) at 5x the error, so they integrate; where the
/// magnification is within a band over the box, below a pixel per voxel, they supersample (issue 37). Levels above 0
/// are not supersampled: level 1 at 1/64 over 32 sub-pixels was 0.15% / 0.32% off (integrated: 0.08% / 0.17%).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "pcvr/camera.h"
#include "pcvr/grid.h"
#include "pcvr/stride.h"
#include "view/view_projection.h"

namespace pcvr {

/// Automatic levels keep the coarse voxels at most this many pixels wide (where they are most
/// magnified): see the table above.
constexpr double kLevelPixelsPerVoxel = 1.0 / 32.0;

/// Where every voxel (of level 0) projects to at most this many pixels, an automatic level renders the
/// image supersampled and box-averages it: see the table above.
constexpr double kSupersampleBelowPixelsPerVoxel = 1.0 / 2.0;

/// The largest side of a supersampled image (16 MiB of floats, per worker): larger views of finer voxels
/// are zoomed out less than 1/8 anyway, or integrate the rest over the sub-pixels' areas.
constexpr int kMaxSupersampledSide = 2048;

/// Supersampling pays where the sub-pixels number at most this many per voxel splatted: a sub-pixel costs
/// about 10 ns (its buffers, the post-convolution, the average), and a voxel integrated over pixels about
/// 100 ns more than one splatted over sub-pixels (one core); half the break-even.
constexpr double kSubPixelsPerVoxel = 4.0;

/// The footprint variance (per axis, index units^2 of level k) of a level-k voxel whose kernel has
/// variance `variance` at level 0.
inline double level_kernel_variance(double variance, int level) {
    const double voxels2 = std::ldexp(1.0, 2 * level);  // 4^k level-0 units^2 per level-k unit^2
    return (variance + (voxels2 - 1.0) / 12.0) / voxels2;
}

/// Which of a footprint's axes corner_pixels_per_voxel measures.
enum class VoxelAxis { MostMagnified, LeastMagnified };

/// The fewest and most pixels per voxel (along the voxel's most magnified direction, or its least) at the
/// corners of the active index box `box`; nullopt when a corner lies behind a perspective eye.
inline std::optional<std::pair<double, double>> corner_pixels_per_voxel(const std::array<int32_t, 6>& box,
                                                                        const Mat4& index_to_world, const Camera& camera,
                                                                        VoxelAxis axis = VoxelAxis::MostMagnified) {
    const ViewProjection view(camera, index_to_world);
    double fewest = std::numeric_limits<double>::infinity(), most = 0;
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p{double(box[(corner & 1) ? 3 : 0]), double(box[(corner & 2) ? 4 : 1]), double(box[(corner & 4) ? 5 : 2])};
        Footprint f;
        if (!view.footprint_unclipped(p, f)) return std::nullopt;
        const double half_trace = 0.5 * (f.qxx + f.qyy);
        const double spread = std::sqrt(0.25 * (f.qxx - f.qyy) * (f.qxx - f.qyy) + f.qxy * f.qxy);
        const double smallest = half_trace - spread;
        if (!(smallest > 0)) return std::nullopt;
        // The form's smallest eigenvalue (index^2 per pixel^2) is along the most magnified direction.
        const double pixels = 1.0 / std::sqrt(axis == VoxelAxis::MostMagnified ? smallest : half_trace + spread);
        fewest = std::min(fewest, pixels);
        most = std::max(most, pixels);
    }
    return std::pair<double, double>{fewest, most};
}

/// The coarsest level whose voxels project to at most `pixels_per_voxel` pixels in every direction
/// at every corner of the active index box `box` (0 when a corner lies behind a perspective eye), and
/// no coarser than two voxels across the box.
inline int automatic_level(const std::array<int32_t, 6>& box, const Mat4& index_to_world, const Camera& camera,
                           double pixels_per_voxel = kLevelPixelsPerVoxel) {
    const auto corners = corner_pixels_per_voxel(box, index_to_world, camera);
    if (!corners) return 0;
    const double most_pixels = corners->second;
    const int extent = std::max({box[3] - box[0], box[4] - box[1], box[5] - box[2]}) + 1;
    int level = 0;
    // The tolerance keeps an exact 1/64 (computed as 0.01562500001) at level 1.
    while ((extent >> (level + 1)) >= 2 && most_pixels * std::ldexp(1.0, level + 1) <= pixels_per_voxel * (1 + 1e-6)) ++level;
    return level;
}

inline int automatic_level(const Grid& grid, const Camera& camera, double pixels_per_voxel = kLevelPixelsPerVoxel) {
    if (grid.active_voxel_count() == 0) return 0;
    return automatic_level(grid.index_bbox(), grid.index_to_world(), camera, pixels_per_voxel);
}

/// The sub-pixels per pixel edge an automatic level 0 renders at, to be box-averaged down (see above):
/// enough for a pixel per voxel along every voxel's least magnified direction, where every voxel of the
/// active index box `box` projects to at most kSupersampleBelowPixelsPerVoxel; else 1. Bounded so the
/// supersampled image stays within kMaxSupersampledSide (the voxels still finer are then integrated over
/// the sub-pixels' areas, as without supersampling).
inline int automatic_supersampling(const std::array<int32_t, 6>& box, const Mat4& index_to_world, const Camera& camera) {
    const auto most = corner_pixels_per_voxel(box, index_to_world, camera);
    if (!most) return 1;
    // In a wide perspective the near voxels span more sub-pixels than the far ones need, and the splats cost
    // more: measured 12% faster at most on 128^3 blobs, and 5 times as far from the pixel means. Where the
    // magnification is nearly one over the box (within a band: a narrow field of view, from afar) it renders as
    // orthographic views do, its least magnified voxels taking the threshold: 5 to 7 times faster than
    // integrating its voxels over pixels (tests/bench/perspective_bench.py).
    const bool uniform = camera.orthographic() || most->second <= kPerspectiveBandRatio * most->first;
    if (!uniform || most->first > kSupersampleBelowPixelsPerVoxel * (1 + 1e-6)) return 1;
    const auto least = corner_pixels_per_voxel(box, index_to_world, camera, VoxelAxis::LeastMagnified);
    if (!least) return 1;
    const double wanted = std::ceil(1.0 / least->first * (1 - 1e-9));
    const int fits = kMaxSupersampledSide / std::max(camera.width(), camera.height());
    const int factor = int(std::min<double>(wanted, fits));
    return factor >= 2 ? factor : 1;
}

/// `factor`, where an image of `camera` supersampled by it costs less than integrating `voxels` over its
/// pixels; else 1.
inline int supersampling_that_pays(int factor, const Camera& camera, uint64_t voxels) {
    const double sub_pixels = double(camera.width()) * camera.height() * factor * factor;
    return sub_pixels <= kSubPixelsPerVoxel * double(voxels) ? factor : 1;
}

}  // namespace pcvr
