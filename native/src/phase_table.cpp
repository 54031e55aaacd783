#include "pcvr/phase_table.h"

#include <cmath>

namespace pcvr {

PhaseFootprintTable::PhaseFootprintTable(const Kernel& kernel, double qxx, double qxy, double qyy)
    : values_(size_t(kPhases + 1) * (kPhases + 1) * 16) {
    for (int py = 0; py <= kPhases; ++py)
        for (int px = 0; px <= kPhases; ++px) {
            const double fx = double(px) / kPhases, fy = double(py) / kPhases;
            float* w = values_.data() + (size_t(py) * (kPhases + 1) + px) * 16;
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i) {
                    const double dx = i - 1 - fx, dy = j - 1 - fy;
                    const double rho2 = qxx * dx * dx + 2.0 * qxy * dx * dy + qyy * dy * dy;
                    w[j * 4 + i] = float(kernel.line_integral(std::sqrt(std::max(0.0, rho2))));
                }
        }
}

}  // namespace pcvr
