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

    /// The four tabulated phases around a centre and their bilinear blend weights.
    struct Blend {
        const float* entry[4];  ///< 16 weights each: (px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)
        float coeff[4];
    };

    /// For taps (c - 1 + i, r - 1 + j), i, j in [0, 4), of a centre at (c + fx, r + fy) with integer
    /// c, r and fx, fy in [0, 1].
    Blend blend(float fx, float fy) const {
        const float sx = fx * kPhases, sy = fy * kPhases;
        const int px = std::min(kPhases - 1, int(sx)), py = std::min(kPhases - 1, int(sy));
        const float ax = sx - px, ay = sy - py;
        const float* e = values_.data() + (size_t(py) * (kPhases + 1) + px) * 16;
        return {{e, e + 16, e + (kPhases + 1) * 16, e + (kPhases + 2) * 16},
                {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay}};
    }

private:
    std::vector<float> values_;
};

}  // namespace pcvr
