#include "pcvr/splatter.h"

#include "block_voxels.h"
#include "phase_splat.h"
#include "pcvr/phase_table.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define PCVR_AVX2 1
#endif

namespace pcvr {

namespace {

/// The footprint's shape in node units of the target grid, as floats for the tap loops.
struct NodeShape {
    float qxx, qxy, qyy;
    float ext_x, ext_y;  // bounding half-widths of the ellipse rho <= radius
    float area;          // integral of the footprint over the plane, node^2
};

NodeShape node_shape(const Footprint& fp, double stride, double radius) {
    Footprint f = fp;
    const double s2 = stride * stride;
    f.qxx *= s2;
    f.qxy *= s2;
    f.qyy *= s2;
    return {float(f.qxx), float(f.qxy), float(f.qyy), float(f.extent_x(radius)), float(f.extent_y(radius)),
            float(f.area_integral())};
}

// ---------------------------------------------------------------------------------------------
// Deposits: what one voxel writes into the grid around its centre (cx, cy) in storage node units.

/// Footprint taps on every row of the ellipse's bounding box, clipped to the grid. Wide footprints
/// (regular splatting at high magnification) visit only each row's chord of the ellipse; for narrow
/// ones a row is one or two vectors anyway, and the chord's square root would cost more than it saves.
void deposit_footprint(SplatGrid& g, double cx, double cy, const NodeShape& s, float amp, const FootprintTable& table) {
    constexpr float kChordWidth = 8.0f;  // half-width in nodes from which rows are trimmed to the chord
    const int r0 = std::max(0, int(std::ceil(cy - s.ext_y)));
    const int r1 = std::min(g.rows() - 1, int(std::floor(cy + s.ext_y)));
    const int box_c0 = std::max(0, int(std::ceil(cx - s.ext_x)));
    const int box_c1 = std::min(g.columns() - 1, int(std::floor(cx + s.ext_x)));
    const bool trim_rows = s.ext_x > kChordWidth;
    const double radius2 = table.radius2();
    [[maybe_unused]] const float* tab = table.data();
    [[maybe_unused]] const float scale = table.scale(), max_index = table.max_index();
    for (int r = r0; r <= r1; ++r) {
        const double dy = r - cy;
        int c0 = box_c0, c1 = box_c1;
        if (trim_rows) {
            // Solve qxx dx^2 + 2 qxy dy dx + qyy dy^2 <= R^2 for the columns inside the ellipse.
            const double b = double(s.qxy) * dy, c = double(s.qyy) * dy * dy - radius2;
            const double disc = b * b - double(s.qxx) * c;
            if (disc <= 0) continue;
            const double root = std::sqrt(disc);
            c0 = std::max(c0, int(std::ceil(cx + (-b - root) / s.qxx)));
            c1 = std::min(c1, int(std::floor(cx + (-b + root) / s.qxx)));
        }
        double* out = g.row(r);
        const float fdy = float(dy), lin = 2.0f * s.qxy * fdy, base = s.qyy * fdy * fdy;
        const float first_dx = float(c0 - cx);
#ifdef PCVR_AVX2
        // Whole 8-lane vectors; lanes past c1 (outside the ellipse, or past the grid's edge) are masked
        // to zero weight, and the grid is padded so that their stores stay inside it.
        const __m256 lanes = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
        for (int col = c0; col <= c1; col += 8) {
            const __m256 dx = _mm256_add_ps(_mm256_set1_ps(first_dx + float(col - c0)), lanes);
            const __m256 r2 = _mm256_fmadd_ps(_mm256_fmadd_ps(_mm256_set1_ps(s.qxx), dx, _mm256_set1_ps(lin)), dx,
                                              _mm256_set1_ps(base));
            const __m256i idx = _mm256_cvttps_epi32(
                _mm256_max_ps(_mm256_min_ps(_mm256_mul_ps(r2, _mm256_set1_ps(scale)), _mm256_set1_ps(max_index)),
                              _mm256_setzero_ps()));
            const __m256 inside = _mm256_cmp_ps(lanes, _mm256_set1_ps(float(c1 - col)), _CMP_LE_OQ);
            const __m256 w = _mm256_and_ps(_mm256_mul_ps(_mm256_i32gather_ps(tab, idx, 4), _mm256_set1_ps(amp)), inside);
            double* o = out + col;
            _mm256_storeu_pd(o, _mm256_add_pd(_mm256_loadu_pd(o), _mm256_cvtps_pd(_mm256_castps256_ps128(w))));
            _mm256_storeu_pd(o + 4, _mm256_add_pd(_mm256_loadu_pd(o + 4), _mm256_cvtps_pd(_mm256_extractf128_ps(w, 1))));
        }
#else
        for (int col = c0; col <= c1; ++col) {
            const float dx = first_dx + float(col - c0);
            out[col] += double(amp * table.at_rho2(std::max(0.0f, (s.qxx * dx + lin) * dx + base)));
        }
#endif
    }
}

/// The common PCVR case: the footprint fits 4 x 4 nodes (|offset| < 2 in node units on both axes).
/// `col`, `row`: the top-left tap, floor(centre) - 1; fx, fy: centre minus that tap, in [1, 2).
inline void deposit_footprint_4x4(SplatGrid& g, int col, int row, float fx, float fy, const NodeShape& s, float amp,
                                  const FootprintTable& table) {
#ifdef PCVR_AVX2
    const __m256 dx = _mm256_sub_ps(_mm256_setr_ps(0, 1, 2, 3, 0, 1, 2, 3), _mm256_set1_ps(fx));
    const __m256 qxx_dx = _mm256_mul_ps(_mm256_set1_ps(s.qxx), dx);
    const __m256 qxy2_dx = _mm256_mul_ps(_mm256_set1_ps(2.0f * s.qxy), dx);
    const __m256 scale = _mm256_set1_ps(table.scale()), max_index = _mm256_set1_ps(table.max_index());
    const __m256 amp8 = _mm256_set1_ps(amp);
    for (int half = 0; half < 2; ++half) {
        const __m256 dy = _mm256_sub_ps(_mm256_setr_ps(0, 0, 0, 0, 1, 1, 1, 1), _mm256_set1_ps(fy - 2.0f * half));
        // rho^2 = qxx dx^2 + (2 qxy dx + qyy dy) dy, non-negative up to rounding
        const __m256 r2 = _mm256_fmadd_ps(qxx_dx, dx, _mm256_mul_ps(_mm256_fmadd_ps(_mm256_set1_ps(s.qyy), dy, qxy2_dx), dy));
        const __m256i idx = _mm256_cvttps_epi32(_mm256_max_ps(_mm256_min_ps(_mm256_mul_ps(r2, scale), max_index), _mm256_setzero_ps()));
        const __m256 w = _mm256_mul_ps(_mm256_i32gather_ps(table.data(), idx, 4), amp8);
        double* a = g.row(row + 2 * half) + col;
        double* b = g.row(row + 2 * half + 1) + col;
        _mm256_storeu_pd(a, _mm256_add_pd(_mm256_loadu_pd(a), _mm256_cvtps_pd(_mm256_castps256_ps128(w))));
        _mm256_storeu_pd(b, _mm256_add_pd(_mm256_loadu_pd(b), _mm256_cvtps_pd(_mm256_extractf128_ps(w, 1))));
    }
#else
    for (int j = 0; j < 4; ++j) {
        double* out = g.row(row + j) + col;
        const float dy = float(j) - fy;
        for (int i = 0; i < 4; ++i) {
            const float dx = float(i) - fx;
            out[i] += double(amp * table.at_rho2(std::max(0.0f, s.qxx * dx * dx + 2.0f * s.qxy * dx * dy + s.qyy * dy * dy)));
        }
    }
#endif
}

/// Westenberg-Roerdink: the footprint's whole integral, spread bilinearly to the 2 x 2 nearest nodes.
inline void deposit_bilinear(SplatGrid& g, double cx, double cy, float mass) {
    const int c = int(std::floor(cx)), r = int(std::floor(cy));
    const double fx = cx - c, fy = cy - r;
    const double w[2][2] = {{(1 - fx) * (1 - fy), fx * (1 - fy)}, {(1 - fx) * fy, fx * fy}};
    for (int j = 0; j < 2; ++j) {
        if (r + j < 0 || r + j >= g.rows()) continue;
        double* out = g.row(r + j);
        for (int i = 0; i < 2; ++i)
            if (c + i >= 0 && c + i < g.columns()) out[c + i] += mass * w[j][i];
    }
}

// ---------------------------------------------------------------------------------------------

/// Splats one voxel whose footprint is known, choosing the cheapest deposit that is exact for it.
struct Depositor {
    SplatGrid& grid;
    const SplatParams& params;
    double inv_stride;

    /// Pixel centre -> storage node coordinates.
    double node_x(double px) const { return px * inv_stride - grid.first_node_x(); }
    double node_y(double py) const { return py * inv_stride - grid.first_node_y(); }

    void operator()(double cx, double cy, const NodeShape& s, float amp) {
        if (params.mode == SplatMode::BilinearSpread) {
            deposit_bilinear(grid, cx, cy, amp * s.area);
            return;
        }
        const int fc = int(std::floor(cx)), fr = int(std::floor(cy));
        if (s.ext_x <= 2.0f && s.ext_y <= 2.0f && fc >= 1 && fr >= 1 && fc + 2 < grid.columns() && fr + 2 < grid.rows()) {
            deposit_footprint_4x4(grid, fc - 1, fr - 1, float(cx - (fc - 1)), float(cy - (fr - 1)), s, amp, *params.table);
            return;
        }
        deposit_footprint(grid, cx, cy, s, amp, *params.table);
    }
};

/// What an orthographic view shares across all voxels: one footprint shape, and node coordinates
/// that are an affine function of the index.
struct OrthographicSetup {
    NodeShape shape;
    OrthographicMapping map;
};

OrthographicSetup orthographic_setup(const ViewProjection& view, const SplatGrid& target, const SplatParams& params) {
    // Differences of exact projections, so nothing is assumed beyond the camera's own affinity check.
    const double inv_stride = 1.0 / target.stride();
    Footprint f0, fi, fj, fk;
    view.footprint_unclipped({0, 0, 0}, f0);
    view.footprint_unclipped({1, 0, 0}, fi);
    view.footprint_unclipped({0, 1, 0}, fj);
    view.footprint_unclipped({0, 0, 1}, fk);
    OrthographicSetup o;
    o.shape = node_shape(f0, target.stride(), params.kernel_radius);
    o.map.amp_per_value = float(params.density_scale * f0.line_scale);
    o.map.gx = Vec3{fi.px - f0.px, fj.px - f0.px, fk.px - f0.px} * inv_stride;
    o.map.gy = Vec3{fi.py - f0.py, fj.py - f0.py, fk.py - f0.py} * inv_stride;
    o.map.bx = f0.px * inv_stride - target.first_node_x();
    o.map.by = f0.py * inv_stride - target.first_node_y();
    return o;
}

/// Orthographic views without a phase table (the box kernel, whose footprint has an edge that
/// interpolation between phases would blur, and footprints too wide to tabulate): node coordinates
/// by three multiply-adds per voxel, then the general deposit.
uint64_t splat_block_orthographic(const VoxelBlock& block, bool clip_test, const ViewProjection& view,
                                  const OrthographicSetup& o, Depositor& deposit) {
    uint64_t count = 0;
    for_each_voxel(block, [&](int offset, float v) {
        const Vec3 p = voxel_position(block, offset);
        if (clip_test && !ViewProjection::inside_clip_range(view.to_clip(p))) return;
        deposit(o.map.node_x(p), o.map.node_y(p), o.shape, o.map.amp_per_value * v);
        ++count;
    });
    return count;
}

/// Perspective views: each voxel's own footprint (size and shape change with depth and position).
uint64_t splat_block_perspective(const VoxelBlock& block, const ViewProjection& view, double stride,
                                 const SplatParams& params, Depositor& deposit) {
    uint64_t count = 0;
    for_each_voxel(block, [&](int offset, float v) {
        Footprint fp;
        if (!view.footprint(voxel_position(block, offset), fp)) return;
        const NodeShape shape = node_shape(fp, stride, params.kernel_radius);
        deposit(deposit.node_x(fp.px), deposit.node_y(fp.py), shape, float(v * params.density_scale * fp.line_scale));
        ++count;
    });
    return count;
}

}  // namespace

uint64_t splat_blocks(const std::vector<VoxelBlock>& grid_blocks, const std::vector<PlannedBlock>& blocks,
                      const ViewProjection& view, const SplatParams& params, SplatGrid& target, RenderControl& control) {
    const double stride = target.stride();
    std::optional<OrthographicSetup> ortho;
    std::optional<PhaseFootprintTable> phases;
    if (view.orthographic()) {
        ortho = orthographic_setup(view, target, params);
        const int half_width = int(std::ceil(std::max(ortho->shape.ext_x, ortho->shape.ext_y) - 1e-4f));
        if (params.mode == SplatMode::BilinearSpread) {
            // The footprint's whole integral goes to the 2 x 2 nearest nodes: the amplitude becomes a mass.
            phases.emplace(PhaseFootprintTable::bilinear_spread());
            ortho->map.amp_per_value *= ortho->shape.area;
        } else if (params.kernel->smooth_footprint() && half_width <= PhaseFootprintTable::kMaxHalfWidth) {
            phases.emplace(*params.kernel, ortho->shape.qxx, ortho->shape.qxy, ortho->shape.qyy, std::max(half_width, 2));
        }
    }

    tbb::enumerable_thread_specific<SplatGrid> locals([&] { return target.zero_like(); });
    tbb::enumerable_thread_specific<uint64_t> counts(0);
    tbb::enumerable_thread_specific<PhaseScratch> scratches;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks.size(), 4), [&](const tbb::blocked_range<size_t>& range) {
        control.throw_if_cancelled();
        SplatGrid& grid = locals.local();
        Depositor deposit{grid, params, 1.0 / stride};
        uint64_t& count = counts.local();
        PhaseScratch& scratch = scratches.local();
        for (size_t b = range.begin(); b != range.end(); ++b) {
            const PlannedBlock& pb = blocks[b];
            const VoxelBlock& block = grid_blocks[pb.index];
            const uint64_t n = !ortho   ? splat_block_perspective(block, view, stride, params, deposit)
                               : phases ? splat_block_phases(block, ortho->map, *phases, pb.needs_clip_test ? &view : nullptr, grid, scratch)
                                        : splat_block_orthographic(block, pb.needs_clip_test, view, *ortho, deposit);
            if (n == 0) continue;
            count += n;
            // The plan's bounds hold every node the block can reach; the post-convolution skips the rest.
            grid.mark(int(std::floor(deposit.node_x(std::max(pb.min_x, -1e9f)))), int(std::floor(deposit.node_y(std::max(pb.min_y, -1e9f)))),
                      int(std::ceil(deposit.node_x(std::min(pb.max_x, 1e9f)))), int(std::ceil(deposit.node_y(std::min(pb.max_y, 1e9f)))));
        }
        control.advance(range.size());
    });
    control.throw_if_cancelled();
    for (const SplatGrid& local : locals) target.add(local);
    uint64_t total = 0;
    for (uint64_t c : counts) total += c;
    return total;
}

}  // namespace pcvr
