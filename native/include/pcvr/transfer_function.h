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
#pragma once

#include <array>
#include <vector>

#include "pcvr/lanes.h"

namespace pcvr {

struct TransferFunction {
    std::vector<double> density;               ///< strictly increasing control points
    std::vector<std::array<double, 4>> rgba;   ///< linear RGB (>= 0) and opacity in [0, 1], one per point
    double unit_distance = 0;                  ///< world units; 0 = the smallest voxel spacing of its grid

    /// Throws InvalidArgument naming the problem: no points, sizes that differ, densities not
    /// increasing, non-finite numbers, colours below 0, opacities outside [0, 1], unit_distance < 0.
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
    /// Linear interpolation between the two nearest entries; densities outside the control points
    /// take the end values (NaN the first).
    Samples operator()(float8 density) const {
        const float8 x = clamp8((density - first_) * scale_, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        const float8 f = x - __builtin_convertvector(i, float8);
        auto lerp = [&](const std::vector<float>& channel) {
            const float8 a = gather8(channel.data(), i), b = gather8(channel.data() + 1, i);
            return a + f * (b - a);
        };
        return {lerp(red_), lerp(green_), lerp(blue_), lerp(extinction_)};
    }
    Sample operator()(float density) const {
        const Samples s = (*this)(broadcast8(density));
        return {s.red[0], s.green[0], s.blue[0], s.extinction[0]};
    }
    /// True when every density in [lo, hi] has zero opacity.
    bool transparent(double lo, double hi) const;
    /// Lanes whose density may be visible: inside the span between the first and the last density
    /// with opacity (a test that saves the lookups where most samples are transparent).
    int8x maybe_opaque(float8 density) const { return (density > opaque_from_) & (density < opaque_to_); }

private:
    float first_, scale_;  // entry index = (density - first) * scale
    // kEntries + 2 entries per channel: the last repeated, so interpolation at the end needs no branch.
    std::vector<float> red_, green_, blue_, extinction_;
    std::vector<int> next_opaque_;  // per entry: the first entry at or after it with extinction > 0
    float opaque_from_, opaque_to_;  // densities outside (opaque_from, opaque_to) have no opacity
};

}  // namespace pcvr
