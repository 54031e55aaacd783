/// @file transfer_function.h
/// @brief Post-classification: the reconstructed density of a sample becomes a colour and an opacity.
///
/// A TransferFunction is what the user gives: control points over increasing density, each with a
/// linear-RGB colour and an opacity `a` meaning "a slab `unit_distance` world units thick stops a
/// fraction a of the light". Between control points both are linear; beyond the first and last they
/// keep the end values. Renderers read a ClassificationTable instead: the same function sampled at
/// kEntries densities, with the opacity turned into an extinction coefficient, so that a sample of any
/// thickness l gets the opacity 1 - (1 - a)^(l / unit_distance) = 1 - exp(-extinction l) (opacity
/// correction: halving the sample spacing leaves the image unchanged). The table also says which
/// density ranges are wholly transparent, so that blocks of voxels that cannot become visible are
/// skipped before they are splatted (what Open VKL's transfer functions report as value ranges).
///
/// Gradient opacity (VTK's GradientOpacity, the `gradientOpacity` of 3D Slicer's presets): optional
/// control points over increasing gradient magnitude |grad density|, in density units per world unit,
/// each with a factor in [0, 1] (piecewise linear, the end values beyond the ends). The factor f scales
/// the opacity per unit_distance before it becomes an extinction, exactly as if the transfer function's
/// opacity at that density were a f: extinction = -ln(1 - a f) / unit_distance, so opacity correction
/// still leaves the image independent of the sample spacing. Since f <= 1 it only removes opacity:
/// the transparent ranges stay valid.
///
/// Emission (optional): one linear-RGB radiance per control point, emitted per world unit of ray
/// length (piecewise linear like the colours). A sample emits whether or not it absorbs, so densities
/// that only emit count as visible: the transparent ranges and maybe_opaque cover emission too.
#pragma once

#include <array>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "pcvr/lanes.h"

namespace pcvr {

class PreintegrationTable;

/// Tables derived from a transfer function once and kept with it: built by the first render that needs
/// them, shared by the function's copies (a render copies the function it is given), freed with the last.
struct TransferFunctionTables {
    std::mutex mutex;
    std::shared_ptr<const PreintegrationTable> preintegration;  ///< src/shaded/classify/preintegration.h
};

struct TransferFunction {
    std::vector<double> density;               ///< strictly increasing control points
    std::vector<std::array<double, 4>> rgba;   ///< linear RGB (>= 0) and opacity in [0, 1], one per point
    double unit_distance = 0;                  ///< world units; 0 = the smallest voxel spacing of its grid
    std::vector<double> gradient;              ///< strictly increasing |gradient| points (>= 0); empty: no modulation
    std::vector<double> gradient_opacity;      ///< opacity factor in [0, 1], one per gradient point
    std::vector<std::array<double, 3>> emission;  ///< radiance per world unit (linear RGB >= 0), one per point; empty: none

    /// Where its derived tables are kept (null: built for each render).
    std::shared_ptr<TransferFunctionTables> tables = std::make_shared<TransferFunctionTables>();

    bool has_gradient_opacity() const { return !gradient.empty(); }
    bool has_emission() const { return !emission.empty(); }

    /// Throws InvalidArgument naming the problem: no points, sizes that differ, densities not
    /// increasing, non-finite numbers, colours below 0, opacities outside [0, 1], unit_distance < 0,
    /// the same for the gradient points (negative magnitudes too) and their factors, and emissions
    /// that are not one finite, non-negative [r, g, b] per point.
    void validate() const;
};

class ClassificationTable {
public:
    static constexpr int kEntries = 4096;

    /// `unit_distance` in world units (> 0): the transfer function's own, or its grid's voxel spacing.
    ClassificationTable(const TransferFunction& tf, double unit_distance);

    struct Sample {
        float red, green, blue;
        float extinction;  ///< per world unit: opacity of a sample l thick is 1 - exp(-extinction l)
    };
    struct Samples {  ///< eight of them
        float8 red, green, blue, extinction;
    };
    struct Emissions {  ///< radiance per world unit, eight samples
        float8 red, green, blue;
    };
    /// Linear interpolation between the two nearest entries; densities outside the control points
    /// take the end values (NaN the first).
    Samples operator()(float8 density) const {
        const float8 x = clamp8((density - first_) * scale_, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        const float8 f = x - __builtin_convertvector(i, float8);
        // A lane's two entries are eight consecutive floats: one load each and a transpose, where
        // four pairs of gathers took three times as long (a fifth of the walk's time at 2048^2).
        float8 c[4];
        lerp_quads8(entries_.data(), i, f, c);
        return {c[0], c[1], c[2], c[3]};
    }
    Sample operator()(float density) const {
        const Samples s = (*this)(broadcast8(density));
        return {s.red[0], s.green[0], s.blue[0], s.extinction[0]};
    }
    /// The extinction alone (what shadow casters need).
    float8 extinction(float8 density) const {
        const float8 x = clamp8((density - first_) * scale_, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        return lerp_entries(extinction_, i, x - __builtin_convertvector(i, float8));
    }
    bool has_gradient_opacity() const { return !gradient_factor_.empty(); }
    bool has_emission() const { return !emit_red_.empty(); }
    /// The emitted radiance per world unit at these densities. Only for tables with emission.
    Emissions emission(float8 density) const {
        const float8 x = clamp8((density - first_) * scale_, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        const float8 f = x - __builtin_convertvector(i, float8);
        return {lerp_entries(emit_red_, i, f), lerp_entries(emit_green_, i, f), lerp_entries(emit_blue_, i, f)};
    }
    struct Emission {
        float red, green, blue;
    };
    Emission emission(float density) const {
        const Emissions e = emission(broadcast8(density));
        return {e.red[0], e.green[0], e.blue[0]};
    }
    /// The extinctions of samples with opacity per unit distance a(density) times the gradient factor
    /// at |gradient| `magnitude`: -ln(1 - a f) / unit_distance. Only for tables with gradient opacity.
    float8 extinction(float8 density, float8 magnitude) const {
        const float8 x = clamp8((density - first_) * scale_, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        const float8 a = lerp_entries(opacity_, i, x - __builtin_convertvector(i, float8));
        const float8 f = gradient_factor(magnitude);
        // The table caps a at 1 - 1e-7, so the logarithm is finite.
        return min8(-log1p8(-a * f) * per_unit_distance_, broadcast8(1e30f));
    }
    float extinction(float density, float magnitude) const { return extinction(broadcast8(density), broadcast8(magnitude))[0]; }
    /// The same for a stretch whose extinction without gradient opacity is `sigma` (a pre-integrated mean):
    /// its opacity per unit distance a = 1 - exp(-sigma unit_distance) times the factor, -ln(1 - a f) /
    /// unit_distance, which is extinction(density, magnitude) where sigma is the extinction at one density.
    float8 extinction_of(float8 sigma, float8 magnitude) const {
        const float8 x = sigma * (1.0f / per_unit_distance_);  // below 0.01 a series: 1 - exp(-x) in float lost its digits
        const float8 a = min8(select8(x < 0.01f, x * (1.0f - x * (0.5f - x * (1.0f / 6.0f))), 1.0f - exp8(-x)),
                              broadcast8(float(1.0 - 1e-7)));
        const float8 f = gradient_factor(magnitude);
        return min8(-log1p8(-a * f) * per_unit_distance_, broadcast8(1e30f));
    }
    /// 1 / unit_distance (capped at 1e30).
    float per_unit_distance() const { return per_unit_distance_; }
    /// True when every density in [lo, hi] has zero opacity and emits nothing.
    bool transparent(double lo, double hi) const;
    /// Lanes whose density may be visible: inside the span between the first and the last density
    /// with opacity or emission (a test that saves the lookups where most samples are transparent).
    int8x maybe_opaque(float8 density) const { return (density > opaque_from_) & (density < opaque_to_); }
    /// Lanes where some density in [lo, hi] may be visible.
    int8x maybe_opaque_within(float8 lo, float8 hi) const { return (hi > opaque_from_) & (lo < opaque_to_); }
    /// The open span (from, to) outside which no density absorbs or emits: all that maybe_opaque reads.
    std::pair<float, float> visible_span() const { return {opaque_from_, opaque_to_}; }

private:
    static constexpr int kGradientEntries = 1024;
    static float8 lerp_entries(const std::vector<float>& table, int8x i, float8 f) { return lerp_pairs8(table.data(), i, f); }
    /// The gradient opacity factor at these magnitudes.
    float8 gradient_factor(float8 magnitude) const {
        const float8 y = clamp8((magnitude - gradient_first_) * gradient_scale_, 0.0f, float(kGradientEntries));
        const int8x j = __builtin_convertvector(y, int8x);
        return lerp_entries(gradient_factor_, j, y - __builtin_convertvector(j, float8));
    }

    float first_, scale_;  // entry index = (density - first) * scale
    // kEntries + 2 entries per channel: the last repeated, so interpolation at the end needs no branch.
    std::vector<float> entries_;     // red, green, blue and extinction of each entry, side by side
    std::vector<float> extinction_;  // the extinctions again, for lookups of them alone
    std::vector<float> emit_red_, emit_green_, emit_blue_;  // like the colours; empty without emission
    std::vector<int> next_opaque_;  // per entry: the first entry at or after it that absorbs or emits
    float opaque_from_, opaque_to_;  // densities outside (opaque_from, opaque_to) neither absorb nor emit
    // Gradient opacity only (empty without): the opacity per unit distance beside the extinction, and
    // the factor over kGradientEntries + 2 magnitudes from gradient_first by 1 / gradient_scale.
    std::vector<float> opacity_, gradient_factor_;
    float gradient_first_ = 0, gradient_scale_ = 0, per_unit_distance_ = 0;
};

}  // namespace pcvr
