/// @file kernel.h
/// @brief Spherically symmetric reconstruction kernels and their pre-integrated footprints.
///
/// | name       | profile h(r)      | radius (voxels)          | note                                   |
/// |------------|-------------------|--------------------------|----------------------------------------|
/// | "gauss1.4" | exp(-1.4 r^2)     | 2                        | the paper's 3D-G: little aliasing      |
/// | "gauss2.0" | exp(-2.0 r^2)     | 2                        | slimmer, sharper, more ripple          |
/// | "linear"   | 1 - r             | 1                        | 3D-L: what bilinear spreading amounts to |
/// | "box"      | 1                 | (3 / 4pi)^(1/3) ~ 0.62   | unit-volume ball (nearest neighbour)   |
///
/// r is measured in index space, so under an anisotropic or sheared index-to-world transform the
/// kernel is an ellipsoid in world space and its footprint an ellipse. Every kernel is truncated at
/// its radius and normalised to unit integral, which makes the sum over the lattice of voxels a
/// partition of unity up to a small ripple (about 0.5% for gauss1.4).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "pcvr/lanes.h"

namespace pcvr {

enum class KernelShape { Gauss14, Gauss20, Linear, Box };

class Kernel {
public:
    /// Parses "gauss1.4", "gauss2.0", "linear" or "box"; throws InvalidArgument listing the names.
    static Kernel from_name(const std::string& name);
    explicit Kernel(KernelShape shape);

    KernelShape shape() const { return shape_; }
    const char* name() const;
    double radius() const { return radius_; }
    /// Normalised profile h(r).
    double value(double r) const;
    /// Its derivative dh/dr (0 at and beyond the radius; the box's jump there is not a derivative).
    double derivative(double r) const;
    /// Analytic line integral of the normalised kernel along a line at distance rho from its centre,
    /// in index units: integral of h(sqrt(rho^2 + s^2)) ds. No tables: used by the exact reference.
    double line_integral(double rho) const;
    /// The part of it from s0 to s1 along the line (s = 0 where the line passes closest to the
    /// centre): what a line cut by a clip plane keeps. Analytic, like line_integral.
    double segment_integral(double rho, double s0, double s1) const;
    /// Per-axis second moment, index units^2 (how much the kernel blurs).
    double variance() const { return variance_; }
    /// False for the box, whose footprint 2 sqrt(R^2 - rho^2) has an infinite slope at its rim:
    /// interpolating between tabulated phases would smear it, so it is always evaluated per tap.
    bool smooth_footprint() const { return shape_ != KernelShape::Box; }

private:
    KernelShape shape_;
    double radius_;
    double normalisation_;  // 1 / (3-D integral of the truncated raw profile)
    double variance_;
};

/// The footprint (pre-integrated kernel) sampled finely in rho^2, so that a tap costs one multiply-add
/// for rho^2, a conversion and a load. Entry k holds the line integral at the centre of
/// [k, k + 1) * step, so truncating rho^2 * scale to an integer rounds to the nearest sample; entries
/// past the radius are zero, so a clamped index needs no branch.
/// Eight taps at once (`weights`) come from a polynomial in rho^2 instead where one fits the line
/// integral closer than the table's own rounding (gauss1.4: 4.4e-4 against 6.8e-4 of the centre's
/// value). The shaded slab splat takes them: its loop stalled on the table's gather of eight scattered
/// entries. The X-ray's footprint loop, a gather and an add per eight taps, stays with the table, which
/// measured faster there (the ten multiply-adds cost more than the gather they replace).
class FootprintTable {
public:
    static constexpr int kSamples = 4096;
    static constexpr int kFitDegree = 10;

    explicit FootprintTable(const Kernel& kernel);
    /// The table of a kernel, made once per shape and kept (its fit evaluates the line integral some
    /// 40 000 times: a millisecond, which a small X-ray render must not pay each time).
    static const FootprintTable& of(const Kernel& kernel);

    float radius2() const { return radius2_; }
    float scale() const { return scale_; }          ///< samples per unit of rho^2
    float max_index() const { return float(kSamples); }  ///< clamp target: a zero entry
    const float* data() const { return values_.data(); }
    float at_rho2(float rho2) const {
        float f = rho2 * scale_;
        return values_[f < float(kSamples) ? int(f) : kSamples];
    }
    /// The footprint at eight values of rho^2 (any: negative rounding is the centre, beyond the radius 0).
    float8 weights(float8 rho2) const {
        rho2 = max8(rho2, broadcast8(0.0f));
        if (!fitted_) return gather8(values_.data(), __builtin_convertvector(min8(rho2 * scale_, broadcast8(max_index())), int8x));
        const float8 x = rho2 * fit_scale_ - 1.0f;  // [0, R^2] to [-1, 1]
        // Estrin's scheme: five multiply-adds deep instead of Horner's ten (the deposit waits on them).
        static_assert(kFitDegree == 10, "Estrin's tree below is written for degree 10");
        const float8 x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
        auto pair = [&](int i) { return fit_[i + 1] * x + fit_[i]; };
        const float8 low = (pair(2) * x2 + pair(0)) + x4 * (pair(6) * x2 + pair(4));
        const float8 high = fit_[10] * x2 + pair(8);
        const float8 p = high * x8 + low;
        return select8(rho2 < radius2_, p, broadcast8(0.0f));
    }
    /// Whether weights() evaluates the polynomial.
    bool fitted() const { return fitted_; }

private:
    float radius2_, scale_;
    std::vector<float> values_;  // kSamples + padding, zero past the radius
    bool fitted_ = false;
    float fit_scale_ = 0;
    std::array<float, kFitDegree + 1> fit_{};  // monomial coefficients in x = 2 rho^2 / R^2 - 1
};

}  // namespace pcvr
