#include "splat/footprint_splat.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "splat/block_linearisation.h"
#include "splat/phase_splat.h"
#include "splat/phase_table_cache.h"
#include "splat/pixel_prefilter.h"
#include "volume/block_voxels.h"

namespace pcvr {

namespace {

/// A footprint in node units of the target grid, as floats for the tap loops.
struct NodeShape {
    float qxx, qxy, qyy;
    float ext_x, ext_y;  // bounding half-widths of the ellipse rho <= radius (plus the prefilter's reach)
    float sigma_x = 0, sigma_y = 0;  // > 0: narrower than a pixel, prefiltered along the pixel axes
    bool widened = false;            // narrower than a pixel, tilted: the form widened by the box's variance
};

#ifdef PCVR_AVX2
/// Footprint weights amp * P(rho^2) of eight taps, zero in lanes not `inside`.
inline __m256 tap_weights(__m256 rho2, float amp, __m256 inside, const FootprintTable& table) {
    const __m256i idx = _mm256_cvttps_epi32(_mm256_max_ps(
        _mm256_min_ps(_mm256_mul_ps(rho2, _mm256_set1_ps(table.scale())), _mm256_set1_ps(table.max_index())),
        _mm256_setzero_ps()));
    return _mm256_and_ps(_mm256_mul_ps(_mm256_i32gather_ps(table.data(), idx, 4), _mm256_set1_ps(amp)), inside);
}
#endif

/// Footprint taps on every row of the ellipse's bounding box around (cx, cy), clipped to
/// rows x columns nodes at `base` (row pitch `pitch`): the grid (T = double) or a block tile
/// (T = float). Wide footprints (regular splatting at high magnification) visit only each row's
/// chord of the ellipse; for narrow ones a row is one or two vectors anyway, and the chord's square
/// root would cost more than it saves. Rows are written in whole 8-lane vectors, lanes past the
/// footprint holding zero weight: the grid's padding and the tile's slack take those stores.
/// Returns the number of taps evaluated.
template <class T>
uint64_t add_footprint(T* base, size_t pitch, int rows, int columns, double cx, double cy, const NodeShape& s, float amp,
                   const FootprintTable& table) {
    constexpr float kChordWidth = 8.0f;  // half-width in nodes from which rows are trimmed to the chord
    const int r0 = clamp_to_int(std::ceil(cy - s.ext_y), 0, rows), r1 = clamp_to_int(std::floor(cy + s.ext_y), -1, rows - 1);
    const int box_c0 = clamp_to_int(std::ceil(cx - s.ext_x), 0, columns);
    const int box_c1 = clamp_to_int(std::floor(cx + s.ext_x), -1, columns - 1);
#ifdef PCVR_AVX2
    const __m256 lanes = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    if (box_c1 - box_c0 < 8) {
        // One vector per row (PCVR's footprints): the terms in dx are the same on every row.
        const __m256 dx = _mm256_add_ps(_mm256_set1_ps(float(box_c0 - cx)), lanes);
        const __m256 qxx_dx2 = _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(s.qxx), dx), dx);
        const __m256 qxy2_dx = _mm256_mul_ps(_mm256_set1_ps(2.0f * s.qxy), dx);
        const __m256 inside = _mm256_cmp_ps(lanes, _mm256_set1_ps(float(box_c1 - box_c0)), _CMP_LE_OQ);
        for (int r = r0; r <= r1; ++r) {
            const __m256 dy = _mm256_set1_ps(float(r - cy));
            // rho^2 = qxx dx^2 + (2 qxy dx + qyy dy) dy
            const __m256 rho2 = _mm256_fmadd_ps(_mm256_fmadd_ps(_mm256_set1_ps(s.qyy), dy, qxy2_dx), dy, qxx_dx2);
            accumulate8(base + size_t(r) * pitch + box_c0, tap_weights(rho2, amp, inside, table));
        }
        return uint64_t(std::max(0, r1 - r0 + 1)) * uint64_t(box_c1 - box_c0 + 1);
    }
#endif
    const bool trim_rows = s.ext_x > kChordWidth;
    const double radius2 = table.radius2();
    uint64_t taps = 0;
    for (int r = r0; r <= r1; ++r) {
        const double dy = r - cy;
        int c0 = box_c0, c1 = box_c1;
        if (trim_rows) {
            // Solve qxx dx^2 + 2 qxy dy dx + qyy dy^2 <= R^2 for the columns inside the ellipse.
            const double b = double(s.qxy) * dy, c = double(s.qyy) * dy * dy - radius2;
            const double disc = b * b - double(s.qxx) * c;
            if (disc <= 0) continue;
            const double root = std::sqrt(disc);
            c0 = clamp_to_int(std::ceil(cx + (-b - root) / s.qxx), c0, columns);
            c1 = clamp_to_int(std::floor(cx + (-b + root) / s.qxx), -1, c1);
        }
        T* out = base + size_t(r) * pitch;
        taps += uint64_t(std::max(0, c1 - c0 + 1));
        const float fdy = float(dy), lin = 2.0f * s.qxy * fdy, row_base = s.qyy * fdy * fdy;
        const float first_dx = float(c0 - cx);
#ifdef PCVR_AVX2
        for (int col = c0; col <= c1; col += 8) {
            const __m256 dx = _mm256_add_ps(_mm256_set1_ps(first_dx + float(col - c0)), lanes);
            const __m256 rho2 = _mm256_fmadd_ps(_mm256_fmadd_ps(_mm256_set1_ps(s.qxx), dx, _mm256_set1_ps(lin)), dx,
                                                _mm256_set1_ps(row_base));
            const __m256 inside = _mm256_cmp_ps(lanes, _mm256_set1_ps(float(c1 - col)), _CMP_LE_OQ);
            accumulate8(out + col, tap_weights(rho2, amp, inside, table));
        }
#else
        for (int col = c0; col <= c1; ++col) {
            const float dx = first_dx + float(col - c0);
            out[col] += T(amp * table.at_rho2(std::max(0.0f, (s.qxx * dx + lin) * dx + row_base)));
        }
#endif
    }
    return taps;
}

/// Westenberg-Roerdink: the footprint's whole integral, spread bilinearly to the 2 x 2 nodes around
/// (cx, cy), clipped to rows x columns nodes at `base`.
template <class T>
uint64_t add_bilinear(T* base, size_t pitch, int rows, int columns, double cx, double cy, float mass) {
    const int c = clamp_to_int(std::floor(cx), -2, columns), r = clamp_to_int(std::floor(cy), -2, rows);
    const double fx = cx - c, fy = cy - r;
    const double w[2][2] = {{(1 - fx) * (1 - fy), fx * (1 - fy)}, {(1 - fx) * fy, fx * fy}};
    for (int j = 0; j < 2; ++j) {
        if (r + j < 0 || r + j >= rows) continue;
        T* out = base + size_t(r + j) * pitch;
        for (int i = 0; i < 2; ++i)
            if (c + i >= 0 && c + i < columns) out[c + i] += T(mass * w[j][i]);
    }
    return 4;
}

/// Where a block's footprints go: a tile around the block's planned bounds when the block is dense
/// enough and they fit one, else the grid. (ref_x, ref_y): the storage node that lane positions are
/// relative to, so that floats keep them exact to about 1e-6 node.
struct BlockTarget {
    DepositRegion region;
    int ref_x = 0, ref_y = 0;
};

BlockTarget block_target(const VoxelBlock& block, const PlannedBlock& planned, const SplatGrid& grid) {
    BlockTarget t;
    t.region = DepositRegion::whole(grid);
    // One node of margin around the plan's bounds for rounding.
    const double x0 = std::floor(grid.node_x(double(planned.min_x))) - 1, x1 = std::ceil(grid.node_x(double(planned.max_x))) + 1;
    const double y0 = std::floor(grid.node_y(double(planned.min_y))) - 1, y1 = std::ceil(grid.node_y(double(planned.max_y))) + 1;
    t.ref_x = clamp_to_int(x0, 0, grid.columns());
    t.ref_y = clamp_to_int(y0, 0, grid.rows());
    // The plan culls blocks that miss the grid, so bounds this narrow lie on it (unknown ones are +-1e30).
    const bool narrow = x1 - x0 < kTileFloats && y1 - y0 < kTileFloats;
    if (narrow && active_count(block) >= kTileMinVoxels) {
        // 8 floats of slack after each row for whole-vector rows.
        t.region = DepositRegion::tile_or_grid(int(x0), int(y0), int(x1 - x0) + 1, int(y1 - y0) + 1, 8, grid);
        if (t.region.tiled) t.ref_x = int(x0), t.ref_y = int(y0);
    }
    return t;
}

/// Adds one footprint, given relative to the block target's reference node, into its tile when it
/// lies inside, else into the grid. Returns the number of taps evaluated.
/// Prefiltered footprints (whose `amp` is their mass) go there whatever the mode.
uint64_t add_lane(const BlockTarget& t, float* tile, SplatGrid& grid, float cx, float cy, const NodeShape& s, float amp,
                  const FootprintSplatParams& params) {
    const DepositRegion& r = t.region;
    const bool prefiltered = s.sigma_x > 0, bilinear = params.bilinear_spread && !prefiltered && !s.widened;
    const PrefilteredShape box{s.sigma_x, s.sigma_y, s.ext_x, s.ext_y, float(kPrefilterReach / grid.stride())};
    if (r.tiled) {
        const bool inside = bilinear ? cx >= 0 && cy >= 0 && cx < r.width - 1 && cy < r.height - 1
                                     : cx - s.ext_x > 0 && cy - s.ext_y > 0 && cx + s.ext_x < r.width - 1 && cy + s.ext_y < r.height - 1;
        if (inside)
            return prefiltered ? add_prefiltered(tile, r.pitch, r.height, r.width, cx, cy, box, amp)
                   : bilinear  ? add_bilinear(tile, r.pitch, r.height, r.width, cx, cy, amp)
                               : add_footprint(tile, r.pitch, r.height, r.width, cx, cy, s, amp, *params.table);
    }
    const double gx = double(cx) + t.ref_x, gy = double(cy) + t.ref_y;
    return prefiltered ? add_prefiltered(grid.row(0), grid.columns(), grid.rows(), grid.columns(), gx, gy, box, amp)
           : bilinear  ? add_bilinear(grid.row(0), grid.columns(), grid.rows(), grid.columns(), gx, gy, amp)
                       : add_footprint(grid.row(0), grid.columns(), grid.rows(), grid.columns(), gx, gy, s, amp, *params.table);
}

#ifdef PCVR_AVX2

typedef double double4 __attribute__((vector_size(32)));
typedef long long long4 __attribute__((vector_size(32)));  // what comparisons of double4 give

inline double4 lanes_of(__m128 v) { return double4(_mm256_cvtps_pd(v)); }
inline __m128 floats_of(double4 v) { return _mm256_cvtpd_ps(__m256d(v)); }
inline uint32_t mask_of(long4 condition) { return uint32_t(_mm256_movemask_pd(__m256d(condition))); }

/// Eight voxels projected: positions relative to the target's reference node, shape, amplitude.
struct ProjectedBatch {
    alignas(32) float cx[8], cy[8], qxx[8], qxy[8], qyy[8], ext_x[8], ext_y[8], amp[8];
    alignas(32) float sigma_x[8], sigma_y[8];  // 0: sampled at node centres; else prefiltered, amp its mass
    uint32_t live;
    uint32_t widened;  // lanes whose form and amp are widened by the pixel's variance (pixel_prefilter.h)  // lanes holding a finite, non-zero voxel inside the clip range
};

/// The vector pass: index offsets (i, j, k) within the block and values v of eight voxels.
void project(const VoxelBlock& block, __m256 i, __m256 j, __m256 k, __m256 v, const FootprintSplatParams& params,
             const SplatGrid& grid, const BlockTarget& target, ProjectedBatch& out) {
    const ViewProjection& view = *params.view;
    const Mat4& m = view.index_to_clip();
    const double stride2 = double(grid.stride()) * grid.stride(), radius = params.kernel_radius;
    const double prefilter_reach = kPrefilterReach / grid.stride();
    // The largest eigenvalue of the form (index^2 per pixel^2) above which a footprint is prefiltered.
    const double prefilter_above =
        params.antialias ? 1.0 / (kPrefilterBelowPixelsPerVoxel * kPrefilterBelowPixelsPerVoxel) : INFINITY;
    const double4 zero = {0, 0, 0, 0};
    auto sqrt4 = [](double4 x) { return double4(_mm256_sqrt_pd(__m256d(x))); };
    const double box_variance = prefilter_reach * prefilter_reach / 3.0;  // (2 h)^2 / 12
    const double tilt_above = kWidenAboveCovariance / stride2;
    uint32_t inside_clip = 0, widened = 0;
    for (int half = 0; half < 2; ++half) {
        auto part = [half](__m256 x) { return lanes_of(half ? _mm256_extractf128_ps(x, 1) : _mm256_castps256_ps128(x)); };
        const double4 x = part(i) + double(block.origin[0]), y = part(j) + double(block.origin[1]),
                      z = part(k) + double(block.origin[2]);
        auto row = [&](int r) { return x * m.m[r][0] + y * m.m[r][1] + z * m.m[r][2] + m.m[r][3]; };
        const double4 clip_x = row(0), clip_y = row(1), clip_z = row(2), clip_w = row(3);
        inside_clip |= mask_of((clip_w > zero) & (clip_z >= -clip_w) & (clip_z <= clip_w)) << (4 * half);

        const FootprintLanes<double4> f = view.footprint_lanes(x, y, z, clip_x, clip_y, clip_w, sqrt4);
        const double4 qxx = f.qxx * stride2, qxy = f.qxy * stride2, qyy = f.qyy * stride2;
        const double4 det = qxx * qyy - qxy * qxy;
        double4 amp = f.line_scale * double(params.density_scale);
        const double4 mass = amp / sqrt4(det);  // the footprint's integral, node^2
        if (params.bilinear_spread) amp = mass;
        // Fewer than one pixel per voxel in some direction: the largest eigenvalue of the form in pixels.
        const double4 half_trace = 0.5 * (f.qxx + f.qyy), half_difference = 0.5 * (f.qxx - f.qyy);
        long4 narrow = half_trace + sqrt4(half_difference * half_difference + f.qxy * f.qxy) > zero + prefilter_above;
        // The footprint's covariance (node^2) and, for tilted ones wide enough, the form widened by it.
        const double4 var = zero + params.kernel_variance;
        const double4 sxx = var * qyy / det, sxy = -var * qxy / det, syy = var * qxx / det;
        const double4 wxx = sxx + box_variance, wyy = syy + box_variance, wdet = wxx * wyy - sxy * sxy;
        const long4 widen = narrow & (sxy * sxy > zero + tilt_above * tilt_above);
        narrow = narrow & ~widen;
        const double4 reach = narrow ? zero + prefilter_reach : zero;
        const int o = 4 * half;
        _mm_store_ps(out.cx + o, floats_of(grid.node_x(f.px) - double(target.ref_x)));
        _mm_store_ps(out.cy + o, floats_of(grid.node_y(f.py) - double(target.ref_y)));
        _mm_store_ps(out.qxx + o, floats_of(widen ? var * wyy / wdet : qxx));
        _mm_store_ps(out.qxy + o, floats_of(widen ? -var * sxy / wdet : qxy));
        _mm_store_ps(out.qyy + o, floats_of(widen ? var * wxx / wdet : qyy));
        _mm_store_ps(out.ext_x + o, floats_of(widen ? radius * sqrt4(wxx / var) : radius * sqrt4(qyy / det) + reach));
        _mm_store_ps(out.ext_y + o, floats_of(widen ? radius * sqrt4(wyy / var) : radius * sqrt4(qxx / det) + reach));
        // Widened: the same integral, mass = amp' sqrt(det) / var over the widened covariance.
        _mm_store_ps(out.amp + o, floats_of(narrow ? mass : widen ? mass * var / sqrt4(wdet) : amp));
        _mm_store_ps(out.sigma_x + o, floats_of(narrow ? sqrt4(sxx) : zero));
        _mm_store_ps(out.sigma_y + o, floats_of(narrow ? sqrt4(syy) : zero));
        widened |= mask_of(widen) << o;
    }
    _mm256_store_ps(out.amp, _mm256_mul_ps(_mm256_load_ps(out.amp), v));
    out.live = inside_clip & uint32_t(_mm256_movemask_ps(finite_non_zero(v)));
    out.widened = widened;
}

/// The vector pass of a linearised block (block_linearisation.h): the same outputs as project(),
/// from the block's affine models in float. No lane is widened or outside the clip range.
void project_linearised(const BlockLinearisation& lin, __m256 i, __m256 j, __m256 k, __m256 v,
                        const FootprintSplatParams& params, double grid_stride, ProjectedBatch& out) {
    auto eval = [&](const AffineInBlock& f) {
        return _mm256_fmadd_ps(_mm256_set1_ps(f.dk), k,
               _mm256_fmadd_ps(_mm256_set1_ps(f.dj), j, _mm256_fmadd_ps(_mm256_set1_ps(f.di), i, _mm256_set1_ps(f.at))));
    };
    const __m256 w = eval(lin.w);
    _mm256_store_ps(out.cx, _mm256_div_ps(eval(lin.x), w));
    _mm256_store_ps(out.cy, _mm256_div_ps(eval(lin.y), w));
    const __m256 qxx = eval(lin.qxx), qxy = eval(lin.qxy), qyy = eval(lin.qyy);
    const __m256 inv_det = _mm256_div_ps(_mm256_set1_ps(1.0f), _mm256_fmsub_ps(qxx, qyy, _mm256_mul_ps(qxy, qxy)));
    const __m256 radius = _mm256_set1_ps(float(params.kernel_radius));
    _mm256_store_ps(out.qxx, qxx);
    _mm256_store_ps(out.qxy, qxy);
    _mm256_store_ps(out.qyy, qyy);
    _mm256_store_ps(out.ext_x, _mm256_mul_ps(radius, _mm256_sqrt_ps(_mm256_mul_ps(qyy, inv_det))));
    _mm256_store_ps(out.ext_y, _mm256_mul_ps(radius, _mm256_sqrt_ps(_mm256_mul_ps(qxx, inv_det))));
    __m256 amp = _mm256_mul_ps(_mm256_mul_ps(eval(lin.line_scale), _mm256_set1_ps(params.density_scale)), v);
    if (params.bilinear_spread || lin.prefiltered) amp = _mm256_mul_ps(amp, _mm256_sqrt_ps(inv_det));  // the integral, node^2
    _mm256_store_ps(out.amp, amp);
    if (lin.prefiltered) {
        // As in project(): the footprint's covariance in nodes, and the reach of half a pixel more.
        const __m256 variance = _mm256_set1_ps(float(params.kernel_variance));
        const __m256 reach = _mm256_set1_ps(float(kPrefilterReach / grid_stride));
        _mm256_store_ps(out.sigma_x, _mm256_sqrt_ps(_mm256_mul_ps(variance, _mm256_mul_ps(qyy, inv_det))));
        _mm256_store_ps(out.sigma_y, _mm256_sqrt_ps(_mm256_mul_ps(variance, _mm256_mul_ps(qxx, inv_det))));
        _mm256_store_ps(out.ext_x, _mm256_add_ps(_mm256_load_ps(out.ext_x), reach));
        _mm256_store_ps(out.ext_y, _mm256_add_ps(_mm256_load_ps(out.ext_y), reach));
    } else {
        _mm256_store_ps(out.sigma_x, _mm256_setzero_ps());
        _mm256_store_ps(out.sigma_y, _mm256_setzero_ps());
    }
    out.live = uint32_t(_mm256_movemask_ps(finite_non_zero(v)));
    out.widened = 0;
}

/// The node windows of a linearised batch's footprints within the block's tile: first node, and
/// nodes across and down (the ellipse's bounding box).
struct TileWindows {
    alignas(32) int32_t col[8], row[8], columns[8], rows[8];
    uint32_t fits;  // lanes whose window lies inside the tile and is at most 8 nodes wide
};

TileWindows tile_windows(const ProjectedBatch& b, const DepositRegion& region) {
    const __m256 cx = _mm256_load_ps(b.cx), cy = _mm256_load_ps(b.cy);
    const __m256 ext_x = _mm256_load_ps(b.ext_x), ext_y = _mm256_load_ps(b.ext_y);
    const __m256i c0 = _mm256_cvtps_epi32(_mm256_ceil_ps(_mm256_sub_ps(cx, ext_x)));
    const __m256i r0 = _mm256_cvtps_epi32(_mm256_ceil_ps(_mm256_sub_ps(cy, ext_y)));
    const __m256i c1 = _mm256_cvtps_epi32(_mm256_floor_ps(_mm256_add_ps(cx, ext_x)));
    const __m256i r1 = _mm256_cvtps_epi32(_mm256_floor_ps(_mm256_add_ps(cy, ext_y)));
    const __m256i one = _mm256_set1_epi32(1), columns = _mm256_add_epi32(_mm256_sub_epi32(c1, c0), one);
    // Inside as add_lane tests it (one node of margin), and whole 8-float rows within the tile's slack.
    const __m256i outside = _mm256_or_si256(
        _mm256_or_si256(_mm256_cmpgt_epi32(one, c0), _mm256_cmpgt_epi32(one, r0)),
        _mm256_or_si256(_mm256_or_si256(_mm256_cmpgt_epi32(c1, _mm256_set1_epi32(region.width - 2)),
                                        _mm256_cmpgt_epi32(r1, _mm256_set1_epi32(region.height - 2))),
                        _mm256_cmpgt_epi32(columns, _mm256_set1_epi32(8))));
    TileWindows w;
    _mm256_store_si256(reinterpret_cast<__m256i*>(w.col), c0);
    _mm256_store_si256(reinterpret_cast<__m256i*>(w.row), r0);
    _mm256_store_si256(reinterpret_cast<__m256i*>(w.columns), columns);
    _mm256_store_si256(reinterpret_cast<__m256i*>(w.rows), _mm256_add_epi32(_mm256_sub_epi32(r1, r0), one));
    w.fits = region.tiled ? ~uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(outside))) & 0xffu : 0;
    return w;
}

/// Lane l's footprint added into its tile copy (row pitch `pitch`): windows up to four nodes wide
/// two rows per vector (as PCVR's orthographic 4 x 4 windows go), wider ones a row per vector.
/// Returns the number of taps evaluated.
uint64_t add_tile_window(float* tile, size_t pitch, const ProjectedBatch& b, const TileWindows& w, int l,
                         const FootprintTable& table) {
    const int columns = w.columns[l], rows = w.rows[l];
    float* out = tile + size_t(w.row[l]) * pitch + w.col[l];
    const __m256 qxx = _mm256_set1_ps(b.qxx[l]), qxy2 = _mm256_set1_ps(2.0f * b.qxy[l]), qyy = _mm256_set1_ps(b.qyy[l]);
    const float dx0 = float(w.col[l]) - b.cx[l], dy0 = float(w.row[l]) - b.cy[l], amp = b.amp[l];
    const bool paired = columns <= 4;
    const __m256 column = paired ? _mm256_setr_ps(0, 1, 2, 3, 0, 1, 2, 3) : _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 row_of_lane = paired ? _mm256_setr_ps(0, 0, 0, 0, 1, 1, 1, 1) : _mm256_setzero_ps();
    const __m256 dx = _mm256_add_ps(_mm256_set1_ps(dx0), column);
    const __m256 qxx_dx2 = _mm256_mul_ps(_mm256_mul_ps(qxx, dx), dx), qxy2_dx = _mm256_mul_ps(qxy2, dx);
    const __m256 in_columns = _mm256_cmp_ps(column, _mm256_set1_ps(float(columns)), _CMP_LT_OQ);
    const int step = paired ? 2 : 1;
    for (int r = 0; r < rows; r += step, out += step * pitch) {
        const __m256 lane_row = _mm256_add_ps(_mm256_set1_ps(float(r)), row_of_lane);
        const __m256 dy = _mm256_add_ps(_mm256_set1_ps(dy0), lane_row);
        const __m256 rho2 = _mm256_fmadd_ps(_mm256_fmadd_ps(qyy, dy, qxy2_dx), dy, qxx_dx2);
        const __m256 inside = _mm256_and_ps(in_columns, _mm256_cmp_ps(lane_row, _mm256_set1_ps(float(rows)), _CMP_LT_OQ));
        const __m256 weights = tap_weights(rho2, amp, inside, table);
        if (!paired) {
            accumulate8(out, weights);
            continue;
        }
        accumulate4(out, _mm256_castps256_ps128(weights));
        if (r + 1 < rows) accumulate4(out + pitch, _mm256_extractf128_ps(weights, 1));
    }
    return uint64_t(columns) * uint64_t(rows);
}

#endif  // PCVR_AVX2

/// The phase table that stands for a linearised block's footprints (at its centre), or none: pixel-averaged
/// ones in every view (a view meets few), sampled ones where the view's are alike (SplatParams::phase_tables).
const CachedPhaseTable* block_phase_table(const BlockLinearisation& lin, const FootprintSplatParams& params, double stride) {
    if (!kProjectivePhases || !params.kernel || params.bilinear_spread || !(lin.prefiltered || params.phase_tables)) return nullptr;
    thread_local PhaseTableMemo memo;  // consecutive blocks mostly share a table
    auto centre = [](const AffineInBlock& f) { return double(f.at) + 3.5 * (double(f.di) + f.dj + f.dk); };
    const double qxx = centre(lin.qxx), qxy = centre(lin.qxy), qyy = centre(lin.qyy), det = qxx * qyy - qxy * qxy;
    if (!(qxx > 0 && qyy > 0 && det > 0)) return nullptr;
    const PhaseTableKey key = lin.prefiltered ? PhaseTableCache::pixel_averaged_key(*params.kernel, params.level,
                                                                                    std::sqrt(params.kernel_variance * qyy / det),
                                                                                    std::sqrt(params.kernel_variance * qxx / det), stride)
                                              : PhaseTableCache::footprint_key(*params.kernel, qxx, qxy, qyy);
    const CachedPhaseTable& cached = memo.get(key, *params.kernel);
    return cached.table || cached.separable ? &cached : nullptr;
}

}  // namespace

uint64_t splat_block_footprints(const VoxelBlock& block, const PlannedBlock& planned, const FootprintSplatParams& params,
                                SplatGrid& grid, SplatScratch& scratch) {
    const BlockTarget target = block_target(block, planned, grid);
#ifdef PCVR_AVX2
    const std::optional<BlockLinearisation> lin =
        params.view->orthographic() ? std::nullopt
                                    : linearise_block(block, *params.view, grid, target.ref_x, target.ref_y,
                                                      params.antialias, params.kernel_variance);
    if (const CachedPhaseTable* phases = lin ? block_phase_table(*lin, params, grid.stride()) : nullptr) {
        const ProjectiveBlock projected{&*lin, target.ref_x, target.ref_y, params.density_scale, phases->table_det};
        return phases->separable ? splat_block_separable(block, projected, *phases->separable, grid, scratch)
                                 : splat_block_phases(block, projected, *phases->table, grid, scratch);
    }
#endif
    float* tiles = target.region.tiled ? scratch.tile_copies() : nullptr;
    const TileFlush flush(target.region, tiles, grid);
    uint64_t count = 0;
#ifdef PCVR_AVX2
    ProjectedBatch b;
    for_each_batch(block, all_active(block), [](int) { return true; }, [&](__m256 i, __m256 j, __m256 k, __m256 v) {
        uint32_t todo = 0;
        if (lin) {
            project_linearised(*lin, i, j, k, v, params, grid.stride(), b);
            todo = b.live;
            if (!params.bilinear_spread && !lin->prefiltered) {
                const TileWindows windows = tile_windows(b, target.region);
                for (uint32_t fits = b.live & windows.fits; fits; fits &= fits - 1) {
                    const int l = __builtin_ctz(fits);
                    scratch.taps += add_tile_window(tile_copy(tiles, l), target.region.pitch, b, windows, l, *params.table);
                }
                todo &= ~windows.fits;
            }
        } else {
            project(block, i, j, k, v, params, grid, target, b);
            todo = b.live;
        }
        count += __builtin_popcount(b.live);
        for (; todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            float* tile = tiles ? tile_copy(tiles, l) : nullptr;
            scratch.taps += add_lane(target, tile, grid, b.cx[l], b.cy[l],
                                     {b.qxx[l], b.qxy[l], b.qyy[l], b.ext_x[l], b.ext_y[l], b.sigma_x[l], b.sigma_y[l],
                                      bool((b.widened >> l) & 1)},
                                     b.amp[l], params);
        }
    });
#else
    const double stride2 = double(grid.stride()) * grid.stride();
    int turn = 0;
    for_each_voxel(block, [&](int offset, float v) {
        Footprint fp;
        if (!params.view->footprint(voxel_position(block, offset), fp)) return;
        Footprint f = fp;
        f.qxx *= stride2;
        f.qxy *= stride2;
        f.qyy *= stride2;
        NodeShape s{float(f.qxx), float(f.qxy), float(f.qyy), float(f.extent_x(params.kernel_radius)),
                    float(f.extent_y(params.kernel_radius))};
        float amp = float(v * params.density_scale * fp.line_scale);
        const bool narrow = params.antialias && prefiltered(fp);
        if (params.bilinear_spread || narrow) amp *= float(f.area_integral());
        if (narrow) {  // as in project(): the footprint's covariance in nodes, widened when tilted
            const double reach = kPrefilterReach / grid.stride(), var = params.kernel_variance;
            const FootprintCovariance c(f.qxx, f.qxy, f.qyy, var);
            const double sxx = c.xx, sxy = c.xy, syy = c.yy;
            if (c.tilted(grid.stride())) {
                const double wxx = sxx + reach * reach / 3.0, wyy = syy + reach * reach / 3.0, wdet = wxx * wyy - sxy * sxy;
                s = {float(var * wyy / wdet), float(-var * sxy / wdet), float(var * wxx / wdet),
                     float(params.kernel_radius * std::sqrt(wxx / var)), float(params.kernel_radius * std::sqrt(wyy / var))};
                s.widened = true;
                amp *= float(var / std::sqrt(wdet));
            } else {
                s.ext_x += float(reach);
                s.ext_y += float(reach);
                s.sigma_x = float(std::sqrt(sxx));
                s.sigma_y = float(std::sqrt(syy));
            }
        }
        float* tile = tiles ? tile_copy(tiles, turn++) : nullptr;
        scratch.taps += add_lane(target, tile, grid, float(grid.node_x(fp.px) - target.ref_x),
                                 float(grid.node_y(fp.py) - target.ref_y), s, amp, params);
        ++count;
    });
#endif
    return count;
}

}  // namespace pcvr
