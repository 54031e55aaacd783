#include "splat/near_eye_splat.h"

#include <algorithm>
#include <cmath>

#include "volume/block_voxels.h"

namespace pcvr {

namespace {

/// Node rays of a splat grid: direction D(u, v) = a + du u + dv v in index space and W(u, v) in world
/// space for storage node (u, v), both scaled so that |a| = 1 (only ratios of them matter).
struct NodeRays {
    Vec3 a, du, dv;
    Vec3 wa, wdu, wdv;

    NodeRays(const ViewProjection& view, const SplatGrid& grid) {
        // Storage node (u, v) sits on pixel (L (u + x0), L (v + y0)).
        const double stride = grid.stride(), px0 = stride * grid.first_node_x(), py0 = stride * grid.first_node_y();
        const Vec3 d0 = view.index_ray(0, 0).direction;
        const Vec3 w0 = view.world_direction(0, 0);
        const Vec3 dx = view.index_ray(1, 0).direction - d0, dy = view.index_ray(0, 1).direction - d0;
        const Vec3 wx = view.world_direction(1, 0) - w0, wy = view.world_direction(0, 1) - w0;
        a = d0 + dx * px0 + dy * py0;
        wa = w0 + wx * px0 + wy * py0;
        const double norm = 1.0 / length(a);
        a = a * norm;
        du = dx * (stride * norm);
        dv = dy * (stride * norm);
        wa = wa * norm;
        wdu = wx * (stride * norm);
        wdv = wy * (stride * norm);
    }
};

/// Columns [lo, hi] of a row, or nothing when lo > hi.
struct Span {
    int lo = 0, hi = -1;
};

/// Where alpha u^2 + 2 beta u + gamma > 0 on a row of `columns` nodes: up to two spans, each widened
/// by a node (every node is tested exactly afterwards, so a rounding error in a root costs nothing).
int positive_spans(double alpha, double beta, double gamma, int columns, Span out[2]) {
    const Span whole{0, columns - 1};
    auto span = [columns](double lo, double hi) {
        return Span{clamp_to_int(std::floor(lo) - 1, 0, columns), clamp_to_int(std::ceil(hi) + 1, -1, columns - 1)};
    };
    if (alpha == 0.0) {
        if (beta == 0.0) return gamma > 0 ? (out[0] = whole, 1) : 0;
        const double root = -gamma / (2.0 * beta);
        out[0] = beta > 0 ? span(root, 1e18) : span(-1e18, root);
        return 1;
    }
    const double disc = beta * beta - alpha * gamma;
    if (disc < 0) return alpha > 0 ? (out[0] = whole, 1) : 0;
    // The roots without cancellation: q / alpha and gamma / q.
    const double q = -(beta + std::copysign(std::sqrt(disc), beta));
    const double r1 = q / alpha, r2 = q != 0.0 ? gamma / q : r1;
    const double lo = std::min(r1, r2), hi = std::max(r1, r2);
    if (alpha < 0) {
        out[0] = span(lo, hi);
        return 1;
    }
    out[0] = span(-1e18, lo);
    out[1] = span(hi, 1e18);
    out[1].lo = std::max(out[1].lo, out[0].hi + 1);  // widened, the two may meet: add no node twice
    return 2;
}

/// One row of a voxel's exact footprint. At column u the node's ray has squared index-space length
/// dd(u) = d0 + u (d1 + u d2), squared world length ww(u) = w0 + u (w1 + u w2), and its dot product
/// with the voxel's offset from the eye is along(u) = a0 + a1 u; the ray passes at rho^2 = |w|^2 -
/// along^2 / dd from the voxel's centre, and adds amp * sqrt(ww / dd) * P(rho^2).
struct RowFootprint {
    double d0, d1, d2, w0, w1, w2, a0, a1;
    double offset2, radius2, amp;

    double weight(double u, const FootprintTable& table) const {
        const double inv_dd = 1.0 / (d0 + u * (d1 + u * d2)), along = a0 + a1 * u;
        const double rho2 = offset2 - along * along * inv_dd;
        if (!(rho2 < radius2)) return 0.0;
        return amp * std::sqrt((w0 + u * (w1 + u * w2)) * inv_dd) * table.at_rho2(float(std::max(rho2, 0.0)));
    }

    /// Adds the weights of columns [lo, hi] to `row`. The vector path writes whole groups of four,
    /// zero past `hi`: the grid's rows are padded (SplatGrid::kPadding).
    void add(double* row, int lo, int hi, const FootprintTable& table) const {
#ifdef PCVR_AVX2
        const __m256d step = _mm256_setr_pd(0, 1, 2, 3);
        for (int u = lo; u <= hi; u += 4) {
            const __m256d x = _mm256_add_pd(_mm256_set1_pd(double(u)), step);
            const __m256d inv_dd = _mm256_div_pd(
                _mm256_set1_pd(1.0),
                _mm256_fmadd_pd(_mm256_fmadd_pd(_mm256_set1_pd(d2), x, _mm256_set1_pd(d1)), x, _mm256_set1_pd(d0)));
            const __m256d ww = _mm256_fmadd_pd(_mm256_fmadd_pd(_mm256_set1_pd(w2), x, _mm256_set1_pd(w1)), x, _mm256_set1_pd(w0));
            const __m256d along = _mm256_fmadd_pd(_mm256_set1_pd(a1), x, _mm256_set1_pd(a0));
            const __m256d rho2 = _mm256_fnmadd_pd(_mm256_mul_pd(along, along), inv_dd, _mm256_set1_pd(offset2));
            const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(rho2, _mm256_set1_pd(radius2), _CMP_LT_OQ),
                                                 _mm256_cmp_pd(x, _mm256_set1_pd(double(hi)), _CMP_LE_OQ));
            const __m128i idx = _mm256_cvttpd_epi32(_mm256_min_pd(
                _mm256_max_pd(_mm256_mul_pd(rho2, _mm256_set1_pd(table.scale())), _mm256_setzero_pd()),
                _mm256_set1_pd(table.max_index())));
            const __m256d p = _mm256_cvtps_pd(_mm_i32gather_ps(table.data(), idx, 4));
            const __m256d w = _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(amp), _mm256_sqrt_pd(_mm256_mul_pd(ww, inv_dd))), p);
            _mm256_storeu_pd(row + u, _mm256_add_pd(_mm256_loadu_pd(row + u), _mm256_and_pd(w, inside)));
        }
#else
        for (int u = lo; u <= hi; ++u) row[u] += weight(double(u), table);
#endif
    }
};

/// Adds one voxel's exact footprint (value `amp`, centre `c`) into the grid. Returns the number of
/// taps evaluated.
uint64_t splat_exact(const Vec3& c, double amp, const Vec3& eye, double radius, const NodeRays& rays,
                 const FootprintTable& table, SplatGrid& grid) {
    const Vec3 w = c - eye;
    const double w2 = dot(w, w), r2 = radius * radius, k = w2 - r2;
    // Per row v: E = a + dv v, and f(u) = (w.E + h u)^2 - k |E + du u|^2 = alpha u^2 + 2 beta u + gamma.
    const double h = dot(w, rays.du), du2 = dot(rays.du, rays.du), wdu2 = dot(rays.wdu, rays.wdu);
    const double alpha = h * h - k * du2;
    const double g0 = dot(w, rays.a), g1 = dot(w, rays.dv);
    const double e0 = dot(rays.a, rays.du), e1 = dot(rays.dv, rays.du);
    const double n0 = dot(rays.a, rays.a), n1 = 2.0 * dot(rays.a, rays.dv), n2 = dot(rays.dv, rays.dv);

    int v0 = 0, v1 = grid.rows() - 1;
    const double b0 = g0 * h - k * e0, b1 = g1 * h - k * e1;
    const double c0 = g0 * g0 - k * n0, c1 = 2.0 * g0 * g1 - k * n1, c2 = g1 * g1 - k * n2;
    if (alpha < 0) {
        // A row is reached where its discriminant beta^2 - alpha gamma, a quadratic in v, is positive.
        Span rows[2];
        const int n = positive_spans(b1 * b1 - alpha * c2, b0 * b1 - 0.5 * alpha * c1, b0 * b0 - alpha * c0, grid.rows(), rows);
        if (n == 0) return 0;
        if (n == 1) v0 = rows[0].lo, v1 = rows[0].hi;  // two spans: the conic's sides; keep every row
    }

    int c_min = grid.columns(), c_max = -1, r_min = grid.rows(), r_max = -1;
    uint64_t taps = 0;
    for (int v = v0; v <= v1; ++v) {
        const double g = g0 + g1 * v, e_du = e0 + e1 * v, e2 = n0 + v * (n1 + v * n2);
        Span spans[2];
        const int n = positive_spans(alpha, g * h - k * e_du, g * g - k * e2, grid.columns(), spans);
        const Vec3 we = rays.wa + rays.wdv * double(v);
        const RowFootprint f{e2, 2.0 * e_du, du2, dot(we, we), 2.0 * dot(we, rays.wdu), wdu2, g, h, w2, r2, amp};
        for (int s = 0; s < n; ++s) {
            if (spans[s].lo > spans[s].hi) continue;
            f.add(grid.row(v), spans[s].lo, spans[s].hi, table);
            taps += uint64_t(spans[s].hi - spans[s].lo + 1);
            c_min = std::min(c_min, spans[s].lo), c_max = std::max(c_max, spans[s].hi);
            r_min = std::min(r_min, v), r_max = std::max(r_max, v);
        }
    }
    if (r_min <= r_max) grid.mark(c_min, r_min, c_max, r_max);
    return taps;
}

}  // namespace

uint64_t splat_block_near_eye(const VoxelBlock& block, const PlannedBlock& planned, const FootprintSplatParams& params,
                              double tolerance, SplatGrid& grid, SplatScratch& scratch) {
    const ViewProjection& view = *params.view;
    const Vec3& eye = view.eye();
    const NodeRays rays(view, grid);
    VoxelBlock far = block;
    uint64_t count = 0;
    for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
        if (!block.active(offset)) continue;
        const Vec3 c = voxel_position(block, offset);
        const ViewProjection::EyeOffset at = view.eye_offset(c);
        if (!(linearised_footprint_error(params.kernel_radius, at.depth, at.lateral, at.line_scale_slope) > tolerance)) continue;
        far.mask[offset >> 6] &= ~(uint64_t(1) << (offset & 63));
        const float value = block.value(offset);
        if (value == 0.0f || !std::isfinite(value) || !ViewProjection::inside_clip_range(view.to_clip(c))) continue;
        scratch.taps += splat_exact(c, double(value) * params.density_scale, eye, params.kernel_radius, rays, *params.table, grid);
        ++count;
    }
    return count + splat_block_footprints(far, planned, params, grid, scratch);
}

}  // namespace pcvr
