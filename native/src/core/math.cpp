#include "pcvr/math.h"

#include <algorithm>
#include <cmath>

namespace pcvr {

Mat4 Mat4::from_rows(const std::array<double, 16>& r) {
    Mat4 out;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) out.m[i][j] = r[i * 4 + j];
    return out;
}

Mat4 Mat4::operator*(const Mat4& o) const {
    Mat4 out;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += m[i][k] * o.m[k][j];
            out.m[i][j] = s;
        }
    return out;
}

Vec4 Mat4::operator*(const Vec4& v) const {
    const double in[4] = {v.x, v.y, v.z, v.w};
    double r[4];
    for (int i = 0; i < 4; ++i) r[i] = m[i][0] * in[0] + m[i][1] * in[1] + m[i][2] * in[2] + m[i][3] * in[3];
    return {r[0], r[1], r[2], r[3]};
}

Vec3 Mat4::transform_point(const Vec3& p) const {
    return {m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]};
}

Vec3 Mat4::transform_vector(const Vec3& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
}

bool Mat4::is_finite() const {
    for (const auto& row : m)
        for (double v : row)
            if (!std::isfinite(v)) return false;
    return true;
}

bool Mat4::is_affine() const {
    return m[3][0] == 0.0 && m[3][1] == 0.0 && m[3][2] == 0.0 && m[3][3] == 1.0;
}

namespace {

/// Gauss-Jordan with partial pivoting of the n x n matrix `a` (row-major, n <= 4) into `out`.
/// "Singular" is judged relative to the matrix's own largest entry, so that a grid with 1e-9
/// voxels is fine while a flattened (rank-deficient) one is not.
bool invert(const double* a_in, int n, double* out) {
    double a[4][8];
    double scale = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            a[i][j] = a_in[i * n + j];
            a[i][j + n] = (i == j) ? 1.0 : 0.0;
            scale = std::max(scale, std::abs(a[i][j]));
        }
    if (!(scale > 0) || !std::isfinite(scale)) return false;
    const double eps = 1e-12 * scale;
    for (int c = 0; c < n; ++c) {
        int pivot = c;
        for (int r = c + 1; r < n; ++r)
            if (std::abs(a[r][c]) > std::abs(a[pivot][c])) pivot = r;
        if (std::abs(a[pivot][c]) <= eps) return false;
        if (pivot != c)
            for (int j = 0; j < 2 * n; ++j) std::swap(a[c][j], a[pivot][j]);
        const double inv = 1.0 / a[c][c];
        for (int j = 0; j < 2 * n; ++j) a[c][j] *= inv;
        for (int r = 0; r < n; ++r) {
            if (r == c) continue;
            const double f = a[r][c];
            if (f == 0.0) continue;
            for (int j = 0; j < 2 * n; ++j) a[r][j] -= f * a[c][j];
        }
    }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) out[i * n + j] = a[i][j + n];
    return true;
}

}  // namespace

std::optional<Mat4> Mat4::inverse() const {
    if (!is_finite()) return std::nullopt;
    Mat4 out;
    if (is_affine()) {
        // [L t; 0 1]^-1 = [L^-1, -L^-1 t; 0 1]. Only L decides singularity: a translation of 1e8
        // must not make 1e-6 voxels look flat next to it.
        double l[9], inv[9];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) l[i * 3 + j] = m[i][j];
        if (!invert(l, 3, inv)) return std::nullopt;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) out.m[i][j] = inv[i * 3 + j];
            out.m[i][3] = -(inv[i * 3] * m[0][3] + inv[i * 3 + 1] * m[1][3] + inv[i * 3 + 2] * m[2][3]);
        }
    } else {
        double flat[16], inv[16];
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) flat[i * 4 + j] = m[i][j];
        if (!invert(flat, 4, inv)) return std::nullopt;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) out.m[i][j] = inv[i * 4 + j];
    }
    if (!out.is_finite()) return std::nullopt;
    return out;
}

double largest_singular_value(const Mat4& m) {
    // The largest eigenvalue of the symmetric A^T A in closed form (Smith, 1961), then its root.
    double a[3][3] = {};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) a[i][j] += m.m[k][i] * m.m[k][j];
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    const double q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    const double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) + (a[2][2] - q) * (a[2][2] - q) + 2.0 * off;
    if (!(p2 > 1e-30 * q * q)) return std::sqrt(std::max({a[0][0], a[1][1], a[2][2]}));
    const double p = std::sqrt(p2 / 6.0);
    double b[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) b[i][j] = (a[i][j] - (i == j ? q : 0.0)) / p;
    const double half_det = 0.5 * (b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0]) +
                                   b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]));
    const double angle = std::acos(std::clamp(half_det, -1.0, 1.0)) / 3.0;
    return std::sqrt(std::max(0.0, q + 2.0 * p * std::cos(angle)));
}

}  // namespace pcvr
