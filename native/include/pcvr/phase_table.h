/// @file phase_table.h
/// @brief A voxel's whole 4 x 4 footprint, tabulated per sub-node phase, for the PCVR fast path.
///
/// When every voxel's footprint has the same shape in node units (orthographic views) and fits
/// 4 x 4 nodes (stride close to the magnification), the 16 weights depend only on where the centre
/// falls inside its node. Tabulating them for kPhases x kPhases phases turns a splat into one 64-byte
/// load and four row updates, with no per-tap table lookups (gathers are slow on many CPUs).
/// The centre is rounded to the nearest phase, 1/128 of a node at most: the resulting jitter has
/// zero mean and a variance below 1e-5 node^2, negligible next to the kernel's own 0.35.
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
    /// with integer c, r and fx, fy in [0, 1).
    const float* weights(float fx, float fy) const {
        const int px = std::min(kPhases - 1, int(fx * kPhases));
        const int py = std::min(kPhases - 1, int(fy * kPhases));
        return values_.data() + (size_t(py) * kPhases + px) * 16;
    }

private:
    std::vector<float> values_;
};

}  // namespace pcvr
