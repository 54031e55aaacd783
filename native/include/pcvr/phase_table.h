/// @file phase_table.h
/// @brief A voxel's whole 4 x 4 footprint, tabulated per sub-node phase, for the PCVR fast path.
///
/// When every voxel's footprint has the same shape in node units (orthographic views) and fits
/// 4 x 4 nodes (stride close to the magnification), the 16 weights depend only on where the centre
/// falls inside its node. Tabulating them at (kPhases + 1)^2 phases and interpolating bilinearly
/// between the four nearest turns a splat into four 64-byte loads, a blend and four row updates,
/// with no per-tap table lookups (gathers are slow on many CPUs). Interpolation keeps the error
/// second order (about 1e-4 of the peak) and, unlike rounding to the nearest phase, free of the
/// coherent sub-pixel shift that axis-aligned views would otherwise show.
#pragma once

#include <algorithm>
#include <vector>

#include "pcvr/kernel.h"

namespace pcvr {

class PhaseFootprintTable {
public:
    static constexpr int kPhases = 32;

    /// The footprint rho^2 = qxx dx^2 + 2 qxy dx dy + qyy dy^2 (node units) of `kernel`.
    PhaseFootprintTable(const Kernel& kernel, double qxx, double qxy, double qyy);

    /// Weights of taps (c - 1 + i, r - 1 + j), i, j in [0, 4), row-major, for a centre at (c + fx, r + fy)
    /// with integer c, r and fx, fy in [0, 1]: `out` receives 16 floats.
    void weights(float fx, float fy, float* out) const {
        const float sx = fx * kPhases, sy = fy * kPhases;
        const int px = std::min(kPhases - 1, int(sx)), py = std::min(kPhases - 1, int(sy));
        const float ax = sx - px, ay = sy - py;
        const float* w00 = entry(px, py);
        const float* w10 = w00 + 16;
        const float* w01 = w00 + (kPhases + 1) * 16;
        const float* w11 = w01 + 16;
        const float c00 = (1 - ax) * (1 - ay), c10 = ax * (1 - ay), c01 = (1 - ax) * ay, c11 = ax * ay;
        for (int t = 0; t < 16; ++t) out[t] = c00 * w00[t] + c10 * w10[t] + c01 * w01[t] + c11 * w11[t];
    }

private:
    const float* entry(int px, int py) const { return values_.data() + (size_t(py) * (kPhases + 1) + px) * 16; }

    std::vector<float> values_;
};

}  // namespace pcvr
