/// @file slab_footprint.h
/// @brief A voxel's kernel cut into slabs by the sheets: what one sheet receives from one footprint tap.
///
/// Image-aligned sheet-buffered splatting (Mueller et al. 1999) cuts space into slabs between planes of
/// constant depth, `spacing` apart, and splats each voxel's kernel slab by slab: a sheet holds, per
/// pixel, the integral of the density along the pixel's ray over its slab. Along a ray passing at
/// distance rho from a voxel's centre (index units), s measures index length from the ray's closest
/// approach to the centre; the slab between depths z_lo and z_hi spans s in [(z_lo - z_q) / kappa,
/// (z_hi - z_q) / kappa], where z_q is the depth of the closest approach (it moves linearly across the
/// footprint when the kernel is sheared relative to the sheets: anisotropic voxels, perspective) and
/// kappa the depth per index length along the ray. The slab's share of the footprint tap is
///
///     P(rho^2) * (D(s_hi) - D(s_lo))
///
/// with P the X-ray footprint (the kernel's whole line integral, kernel.h) and D the cumulative depth
/// profile of the kernel along its central chord, normalised to run from 0 at s = -R to 1 at s = R.
/// The slabs of a voxel therefore add up to its X-ray footprint exactly, for every kernel. For the
/// Gaussians the profile along any chord is the same exp(-a s^2) up to where the truncated kernel
/// ends (at s = +-sqrt(R^2 - rho^2)), so each slab is exact to within that truncation: at most 1e-3 of
/// the footprint's peak, at its rim. For the linear and box kernels the profile changes with rho and
/// the central chord's stands in for all: slabs are approximate, their sum still exact.
///
/// | kernel     | D(s), t = clamp(s / R, -1, 1)                                  |
/// |------------|----------------------------------------------------------------|
/// | "gauss*"   | (1 + erf(sqrt(a) R t) / erf(sqrt(a) R)) / 2, an odd polynomial of degree 17 in t (max error 1e-6, 7e-6 for gauss2.0) |
/// | "linear"   | 1/2 + t - t abs(t) / 2                                          |
/// | "box"      | (1 + t) / 2                                                     |
#pragma once

#include <array>

#include "pcvr/kernel.h"

namespace pcvr {

class DepthProfile {
public:
    static constexpr int kCoefficients = 9;

    explicit DepthProfile(const Kernel& kernel);

    float radius() const { return radius_; }
    /// D(s) for s in index units along the ray (T: float, or a vector of floats with the operations used).
    /// `clamp` limits to [-1, 1]; the result is exactly 0 at and before -R, 1 at and beyond R (so that
    /// a voxel's slab shares add up to 1 to float rounding), between them within float rounding of the
    /// fit and never outside [0, 1].
    template <class T, class Clamp, class Abs>
    T operator()(T s, Clamp clamp, Abs abs) const {
        const T t = clamp(s * inv_radius_);
        const T u = t * t;
        T p = T{} + odd_[kCoefficients - 1];
        for (int i = kCoefficients - 2; i >= 0; --i) p = p * u + odd_[i];
        // 1/2 + t (...) at t = +-1 is 1/2 +- (1/2 + rounding): the sign of t picks the exact end.
        return clamp(2.0f * t * (p + abs_ * abs(t))) * 0.5f + 0.5f;
    }
    float operator()(float s) const {
        return (*this)(s, [](float t) { return t < -1.0f ? -1.0f : (t > 1.0f ? 1.0f : t); }, [](float t) { return t < 0 ? -t : t; });
    }

private:
    float radius_, inv_radius_;
    std::array<float, kCoefficients> odd_{};  // D = 1/2 + t (sum odd_[i] t^2i + abs_ |t|)
    float abs_ = 0;
};

}  // namespace pcvr
