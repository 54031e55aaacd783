#include "pcvr/kernel.h"

#include <algorithm>
#include <cmath>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct ShapeInfo {
    KernelShape shape;
    const char* name;
};
constexpr ShapeInfo kShapes[] = {{KernelShape::Gauss14, "gauss1.4"},
                                 {KernelShape::Gauss20, "gauss2.0"},
                                 {KernelShape::Linear, "linear"},
                                 {KernelShape::Box, "box"}};

double gauss_alpha(KernelShape s) { return s == KernelShape::Gauss14 ? 1.4 : 2.0; }
bool is_gauss(KernelShape s) { return s == KernelShape::Gauss14 || s == KernelShape::Gauss20; }

double raw_profile(KernelShape s, double r, double radius) {
    if (r > radius) return 0.0;  // inclusive, so that integrating up to the radius sees its end value
    if (is_gauss(s)) return std::exp(-gauss_alpha(s) * r * r);
    if (s == KernelShape::Linear) return 1.0 - r / radius;
    return 1.0;
}

// Line integral of the raw (unnormalised) profile at distance rho, closed form for each shape.
double raw_line_integral(KernelShape s, double rho, double radius) {
    if (rho >= radius) return 0.0;
    const double half = std::sqrt(radius * radius - rho * rho);  // half-length of the chord
    if (is_gauss(s)) {
        const double a = gauss_alpha(s);
        return std::exp(-a * rho * rho) * std::sqrt(kPi / a) * std::erf(std::sqrt(a) * half);
    }
    if (s == KernelShape::Linear) {
        // integral of (1 - sqrt(rho^2 + t^2) / R) dt over the chord, radius R:
        // 2h - (h R + rho^2 ln((h + R) / rho)) / R
        if (rho == 0.0) return radius;
        return 2.0 * half - (half * radius + rho * rho * std::log((half + radius) / rho)) / radius;
    }
    return 2.0 * half;
}

// Integral of the raw profile along a line at distance rho, from s = 0 to s (|s| within the chord),
// closed form: odd in s, and the whole line integral is twice its value at the chord's end.
double raw_partial_integral(KernelShape shape, double rho, double s, double radius) {
    if (is_gauss(shape)) {
        const double a = gauss_alpha(shape);
        return std::exp(-a * rho * rho) * 0.5 * std::sqrt(kPi / a) * std::erf(std::sqrt(a) * s);
    }
    if (shape == KernelShape::Linear) {
        // integral of (1 - sqrt(rho^2 + t^2) / R) dt = s - (s q + rho^2 ln((s + q) / rho)) / (2R), q = sqrt(rho^2 + s^2)
        const double q = std::sqrt(rho * rho + s * s), magnitude = std::abs(s);
        const double log_term = rho > 0 ? rho * rho * std::log((magnitude + q) / rho) : 0.0;
        return std::copysign(magnitude - (magnitude * q + log_term) / (2.0 * radius), s);
    }
    return s;
}

// 4 pi * integral of r^k * profile(r) dr over [0, radius], by composite Simpson (smooth enough).
double radial_moment(KernelShape s, double radius, int k) {
    const int n = 20000;
    const double h = radius / n;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
        const double r = i * h;
        const double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
        sum += w * std::pow(r, k) * raw_profile(s, r, radius);
    }
    return 4.0 * kPi * sum * h / 3.0;
}

}  // namespace

Kernel Kernel::from_name(const std::string& name) {
    for (const auto& s : kShapes)
        if (name == s.name) return Kernel(s.shape);
    throw InvalidArgument("unknown splat kernel '" + name + "' (expected gauss1.4, gauss2.0, linear or box)");
}

Kernel::Kernel(KernelShape shape) : shape_(shape) {
    switch (shape) {
        case KernelShape::Gauss14:
        case KernelShape::Gauss20: radius_ = 2.0; break;
        case KernelShape::Linear: radius_ = 1.0; break;
        case KernelShape::Box: radius_ = std::cbrt(3.0 / (4.0 * kPi)); break;
    }
    normalisation_ = 1.0 / radial_moment(shape, radius_, 2);
    // Per-axis second moment: a third of the radial one.
    variance_ = radial_moment(shape, radius_, 4) * normalisation_ / 3.0;
}

const char* Kernel::name() const {
    for (const auto& s : kShapes)
        if (s.shape == shape_) return s.name;
    return "?";
}

double Kernel::value(double r) const { return normalisation_ * raw_profile(shape_, r, radius_); }

double Kernel::derivative(double r) const {
    if (r >= radius_) return 0.0;
    if (is_gauss(shape_)) return -2.0 * gauss_alpha(shape_) * r * value(r);
    if (shape_ == KernelShape::Linear) return -normalisation_ / radius_;
    return 0.0;
}

double Kernel::line_integral(double rho) const {
    return normalisation_ * raw_line_integral(shape_, std::abs(rho), radius_);
}

double Kernel::segment_integral(double rho, double s0, double s1) const {
    rho = std::abs(rho);
    if (rho >= radius_) return 0.0;
    const double half = std::sqrt(radius_ * radius_ - rho * rho);
    s0 = std::clamp(s0, -half, half), s1 = std::clamp(s1, -half, half);
    if (!(s1 > s0)) return 0.0;
    return normalisation_ * (raw_partial_integral(shape_, rho, s1, radius_) - raw_partial_integral(shape_, rho, s0, radius_));
}

FootprintTable::FootprintTable(const Kernel& kernel)
    : radius2_(float(kernel.radius() * kernel.radius())),
      scale_(float(kSamples / (kernel.radius() * kernel.radius()))),
      values_(kSamples + 16, 0.0f) {
    const double step = double(radius2_) / kSamples;
    for (int k = 0; k < kSamples; ++k) values_[k] = float(kernel.line_integral(std::sqrt((k + 0.5) * step)));

    // Chebyshev interpolation in x = 2 rho^2 / R^2 - 1 at the Chebyshev nodes, turned into monomials in x.
    const double r2 = kernel.radius() * kernel.radius();
    constexpr int n = kFitDegree + 1;
    auto footprint = [&](double x) { return kernel.line_integral(std::sqrt(std::max(0.0, (x + 1.0) * 0.5 * r2))); };
    std::array<double, n> chebyshev{};
    for (int k = 0; k < n; ++k) {
        const double angle = kPi * (k + 0.5) / n, value = footprint(std::cos(angle));
        for (int j = 0; j < n; ++j) chebyshev[j] += (j == 0 ? 1.0 : 2.0) / n * value * std::cos(j * angle);
    }
    // T_j as monomials: T_0 = 1, T_1 = x, T_{j+1} = 2x T_j - T_{j-1}.
    std::array<double, n> monomial{}, before{}, current{};
    before[0] = 1.0, current[1] = 1.0;
    monomial[0] = chebyshev[0];
    for (int i = 0; i < n; ++i) monomial[i] += chebyshev[1] * current[i];
    for (int j = 2; j < n; ++j) {
        std::array<double, n> next{};
        for (int i = 0; i < n; ++i) next[i] = (i > 0 ? 2.0 * current[i - 1] : 0.0) - before[i];
        for (int i = 0; i < n; ++i) monomial[i] += chebyshev[j] * next[i];
        before = current, current = next;
    }
    for (int i = 0; i < n; ++i) fit_[i] = float(monomial[i]);
    fit_scale_ = float(2.0 / r2);
    // Kept only where it beats the table's rounding to the nearest sample, everywhere inside the radius.
    double fit_error = 0, table_error = 0;
    for (int k = 0; k <= 8 * kSamples; ++k) {
        const double rho2 = r2 * k / (8.0 * kSamples), exact = kernel.line_integral(std::sqrt(rho2));
        const double x = rho2 * (2.0 / r2) - 1.0;
        double p = monomial[n - 1];
        for (int i = n - 2; i >= 0; --i) p = p * x + monomial[i];
        fit_error = std::max(fit_error, std::abs(p - exact));
        table_error = std::max(table_error, std::abs(double(at_rho2(float(rho2))) - exact));
    }
    fitted_ = fit_error < table_error;
}

const FootprintTable& FootprintTable::of(const Kernel& kernel) {
    static const FootprintTable tables[] = {FootprintTable(Kernel(KernelShape::Gauss14)), FootprintTable(Kernel(KernelShape::Gauss20)),
                                            FootprintTable(Kernel(KernelShape::Linear)), FootprintTable(Kernel(KernelShape::Box))};
    return tables[int(kernel.shape())];
}

}  // namespace pcvr
