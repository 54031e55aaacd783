/// @file pixel_prefilter.h
/// @brief Footprints narrower than a pixel, integrated over each pixel's area (anti-aliased minification).
///
/// A pixel of the reference image is the mean of the line integral over its square, not its value at
/// the centre. Where a voxel projects to a pixel or more the two hardly differ (0.2% relative RMSE at
/// magnification 1 on smooth volumes) and footprints are sampled at pixel centres as before. Below one
/// pixel per voxel a sampled footprint misses or hits each pixel centre by chance: the image aliases,
/// and a 1 x 1 image returns the line integral through its centre, not its mean. There every footprint
/// is replaced by its convolution with the pixel's box, as in elliptical weighted average splatting
/// but with the pixel's own filter instead of a Gaussian standing in for it (a Gaussian of the box's
/// variance, 1/12 pixel^2, sampled at pixel centres keeps only 84% of a point's mass in its pixel and
/// spreads a voxel's mass over its neighbours by up to 19% of it, depending on where it falls).
///
/// The footprint is taken as the Gaussian of the kernel's variance, which makes the convolution with
/// the box separable along the pixel axes: weight(dx, dy) = mass * Bx(dx) * By(dy), with
/// Bx(dx) = Phi((dx + h - cx) / sx) - Phi((dx - h - cx) / sx), sx the footprint's standard deviation
/// along x, h half a pixel (in nodes). This is exact for footprints whose axes are the pixel axes
/// (cubic voxels in orthographic views: every footprint is a circle) and drops the footprint's tilt
/// (its covariance between x and y) otherwise. The weights are normalised over the footprint's
/// reach, so every voxel's integral over the image is its footprint's.
///
/// Footprints tilted by more than kWidenAboveCovariance are widened instead, as in EWA splatting:
/// their covariance in pixels becomes the kernel's plus the box's (1/12 pixel^2 per axis), the form
/// qxx, qxy, qyy follows, and the amplitude is scaled so the integral stays the same; they are then
/// sampled at pixel centres like any footprint. Against pixel means of a smooth volume of voxels
/// 1 : 1.6 : 0.7 (the tests' "scaled") at magnification 1/4, the separable box was 0.37% off and the
/// widened footprint 0.03%; with 20 : 1 voxels 25% and 0.02%. The Gaussian only stands in for the
/// box where the image hardly changes within a pixel, though: where the whole volume covers a pixel
/// or two (magnification 1/64 on 48^3) the widened footprints were 14-15% off and the separable box
/// 0.01% (1 : 1.6 : 0.7) and 5% (20 : 1). The threshold picked the better of the two in every case
/// measured (tests/native/test_xray_minification.py).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pcvr/lanes.h"
#include "pcvr/math.h"
#include "splat/block_tile.h"
#include "view/footprint_limits.h"
#include "view/view_projection.h"

namespace pcvr {

/// Footprints whose covariance between the pixel axes exceeds this (pixel^2) are widened by the
/// box's variance rather than integrated over pixels along the axes (see above).
constexpr double kWidenAboveCovariance = 0.02;


/// The covariance (node^2) of a footprint whose form in nodes is (qxx, qxy, qyy), for a kernel of
/// `variance` per axis: the variance through the form's inverse. (project() in footprint_splat.cpp
/// computes the same eight lanes at a time.)
struct FootprintCovariance {
    double xx, xy, yy;
    FootprintCovariance(double qxx, double qxy, double qyy, double variance) {
        const double det = qxx * qyy - qxy * qxy;
        xx = variance * qyy / det, xy = -variance * qxy / det, yy = variance * qxx / det;
    }
    /// Tilted enough against the pixel axes (grid stride `stride`) to be widened rather than averaged
    /// over pixels along them.
    bool tilted(double stride) const { return std::abs(xy) > kWidenAboveCovariance / (stride * stride); }
};

/// The standard normal distribution function, tabulated (linear interpolation: error < 3e-7).
class NormalCdf {
public:
    static const NormalCdf& instance() {
        static const NormalCdf table;
        return table;
    }
    float operator()(double t) const {
        const double u = (std::clamp(t, -kRange, kRange) + kRange) * kScale;
        const int i = int(u);
        const float f = float(u - i);
        return values_[i] + f * (values_[i + 1] - values_[i]);
    }
    /// Eight at once (float arguments: 1e-6 of a standard deviation is far below the table's steps).
    float8 operator()(float8 t) const {
        const float8 u = (clamp8(t, -float(kRange), float(kRange)) + float(kRange)) * float(kScale);
        const int8x i = __builtin_convertvector(u, int8x);
        return lerp_pairs8(values_.data(), i, u - __builtin_convertvector(i, float8));
    }

private:
    static constexpr int kIntervals = 4096;
    static constexpr double kRange = 6.0;  // Phi(-6) = 1e-9
    static constexpr double kScale = kIntervals / (2 * kRange);
    NormalCdf() : values_(kIntervals + 2) {
        for (int i = 0; i <= kIntervals; ++i) values_[i] = float(0.5 * std::erfc(-(i / kScale - kRange) / std::sqrt(2.0)));
        values_[kIntervals + 1] = values_[kIntervals];  // t = kRange lands on the last interval's end
    }
    std::vector<float> values_;
};

/// A prefiltered footprint in node units of the target grid.
struct PrefilteredShape {
    float sigma_x, sigma_y;  ///< the footprint's standard deviations along the node axes
    float ext_x, ext_y;      ///< half-widths of what it reaches: the kernel's ellipse plus half a pixel
    float half_pixel;        ///< half a pixel in nodes (the box's half-width)
};

/// The prefilter along one axis: the weight of node n, normalised over the nodes [lo, hi] that the
/// footprint reaches (the Gaussian's tails beyond the kernel's reach are dropped, not lost).
class AxisPrefilter {
public:
    AxisPrefilter(double centre, double sigma, double half_pixel, int lo, int hi)
        : cdf_(NormalCdf::instance()), centre_(centre), inv_sigma_(1.0 / sigma), half_(half_pixel), lo_(lo) {
        if (half_pixel == 0.5 && hi - lo < 7) {
            // Nodes one pixel apart (stride 1, where every prefiltered footprint is): node n's box
            // ends where node n + 1's begins, so one vector of edges gives every weight and their sum.
            const float8 edges = cdf_((lane_index8() + float(lo - 0.5 - centre_)) * float(inv_sigma_));
            alignas(32) float e[8];
            store8(e, edges);
            const int nodes = hi - lo + 1;
            const float total = e[nodes] - e[0];
            const float8 next = __builtin_shufflevector(edges, edges, 1, 2, 3, 4, 5, 6, 7, 7);  // gcc 12 and clang
            weights_ = select8(lane_index8() < float(nodes), (next - edges) * (total > 0 ? 1.0f / total : 0.0f), float8{});
            shared_edges_ = true;
            return;
        }
        const double total = edge(hi + half_) - edge(lo - half_);
        scale_ = total > 0 ? 1.0 / total : 0.0;
    }
    /// The weights of nodes first .. first + 7, zero from lane `count` on.
    float8 weights8(int first, int count) const {
        if (shared_edges_ && first == lo_) return select8(lane_index8() < float(count), weights_, float8{});
        const float8 at = (lane_index8() + float(first - centre_)) * float(inv_sigma_);
        const float step = float(half_ * inv_sigma_);
        const float8 w = (cdf_(at + step) - cdf_(at - step)) * float(scale_);
        return select8(lane_index8() < float(count), w, float8{});
    }

private:
    double edge(double at) const { return double(cdf_((at - centre_) * inv_sigma_)); }
    const NormalCdf& cdf_;
    double centre_, inv_sigma_, half_, scale_ = 0;
    int lo_;
    bool shared_edges_ = false;
    float8 weights_{};  // nodes lo .. hi, with shared edges
};

/// Adds `mass` (the footprint's integral in node^2 times the voxel's amplitude) spread by the
/// prefiltered footprint centred at (cx, cy), clipped to rows x columns nodes at `base` (row pitch
/// `pitch`): the grid (T = double) or a block tile (T = float). Rows are written in whole 8-lane
/// vectors, lanes past the footprint holding zero weight (the grid's padding and the tile's slack take
/// those stores), as add_footprint does. Returns the number of taps written.
template <class T>
uint64_t add_prefiltered(T* base, size_t pitch, int rows, int columns, double cx, double cy, const PrefilteredShape& s, float mass) {
    constexpr int kFar = 1 << 30;  // beyond any grid: such footprints are clipped away whole
    const int lo_x = clamp_to_int(std::ceil(cx - s.ext_x), -kFar, kFar), hi_x = clamp_to_int(std::floor(cx + s.ext_x), -kFar, kFar);
    const int lo_y = clamp_to_int(std::ceil(cy - s.ext_y), -kFar, kFar), hi_y = clamp_to_int(std::floor(cy + s.ext_y), -kFar, kFar);
    const int c0 = std::max(lo_x, 0), c1 = std::min(hi_x, columns - 1);
    const int r0 = std::max(lo_y, 0), r1 = std::min(hi_y, rows - 1);
    if (c1 < c0 || r1 < r0) return 0;
    const AxisPrefilter along_x(cx, s.sigma_x, s.half_pixel, lo_x, hi_x), along_y(cy, s.sigma_y, s.half_pixel, lo_y, hi_y);
    constexpr int kChunk = 8;
    for (int col = c0; col <= c1; col += kChunk) {
        const int count = std::min(kChunk, c1 - col + 1);
        const float8 wx = along_x.weights8(col, count);
        for (int row = r0; row <= r1; row += kChunk) {
            const float8 wy = along_y.weights8(row, std::min(kChunk, r1 - row + 1)) * mass;
            for (int r = row; r <= std::min(r1, row + kChunk - 1); ++r) {
                T* out = base + size_t(r) * pitch + col;
#if defined(__AVX2__) && defined(__FMA__)
                accumulate8(out, __m256(wx * wy[r - row]));
#else
                for (int n = 0; n < count; ++n) out[n] += T(wy[r - row] * wx[n]);
#endif
            }
        }
    }
    return uint64_t(c1 - c0 + 1) * uint64_t(r1 - r0 + 1);
}

}  // namespace pcvr
