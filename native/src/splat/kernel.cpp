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
}

}  // namespace pcvr
