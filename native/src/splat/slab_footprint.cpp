#include "splat/slab_footprint.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace pcvr {

namespace {

/// Least squares fit of f(t) ~ t * sum c_i t^(2i) on Chebyshev nodes of (0, 1] (f is odd), by
/// modified Gram-Schmidt: the normal equations of this basis would lose half the digits.
template <class F>
std::array<double, DepthProfile::kCoefficients> fit_odd(F f) {
    constexpr int n = DepthProfile::kCoefficients, m = 400;
    std::vector<std::array<double, n>> a(m);
    std::vector<double> b(m);
    for (int r = 0; r < m; ++r) {
        const double t = std::cos(M_PI * (r + 0.5) / (2 * m));  // in (0, 1]
        double p = t;
        for (int c = 0; c < n; ++c, p *= t * t) a[r][c] = p;
        b[r] = f(t);
    }
    // QR: columns of a become orthonormal q, r upper triangular.
    std::array<std::array<double, n>, n> upper{};
    for (int c = 0; c < n; ++c) {
        for (int k = 0; k < c; ++k) {
            double d = 0;
            for (int r = 0; r < m; ++r) d += a[r][k] * a[r][c];
            upper[k][c] = d;
            for (int r = 0; r < m; ++r) a[r][c] -= d * a[r][k];
        }
        double norm = 0;
        for (int r = 0; r < m; ++r) norm += a[r][c] * a[r][c];
        norm = std::sqrt(norm);
        upper[c][c] = norm;
        for (int r = 0; r < m; ++r) a[r][c] /= norm;
    }
    std::array<double, n> qtb{}, x{};
    for (int c = 0; c < n; ++c)
        for (int r = 0; r < m; ++r) qtb[c] += a[r][c] * b[r];
    for (int c = n - 1; c >= 0; --c) {
        double s = qtb[c];
        for (int k = c + 1; k < n; ++k) s -= upper[c][k] * x[k];
        x[c] = s / upper[c][c];
    }
    return x;
}

}  // namespace

DepthProfile::DepthProfile(const Kernel& kernel) : radius_(float(kernel.radius())), inv_radius_(float(1.0 / kernel.radius())) {
    switch (kernel.shape()) {
        case KernelShape::Gauss14:
        case KernelShape::Gauss20: {
            const double a = kernel.shape() == KernelShape::Gauss14 ? 1.4 : 2.0;
            const double k = std::sqrt(a) * kernel.radius();
            const auto c = fit_odd([k](double t) { return 0.5 * std::erf(k * t) / std::erf(k); });
            // D(R) = 1 exactly, so that a voxel's slabs add up to its whole footprint: scaled so that the
            // polynomial reaches its end value a hair early (2^-20, far below the fit's error) and the
            // clamp makes the ends exact whatever float rounding does.
            double at_radius = 0;
            for (double ci : c) at_radius += ci;
            for (int i = 0; i < kCoefficients; ++i) odd_[i] = float(c[i] * 0.5 / at_radius * (1.0 + std::ldexp(1.0, -20)));
            break;
        }
        case KernelShape::Linear:
            odd_[0] = 1.0f;
            abs_ = -0.5f;
            break;
        case KernelShape::Box: odd_[0] = 0.5f; break;
    }
}


}  // namespace pcvr
