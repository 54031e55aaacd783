#include "pcvr/phase_table.h"

#include <cmath>

namespace pcvr {

namespace {
constexpr size_t kTargetBytes = 256 * 1024;
constexpr int kMostPhases = PhaseFootprintTable::kPhases4x4;
constexpr int kFewestPhases = 4;
}  // namespace

PhaseFootprintTable::PhaseFootprintTable(const Kernel& kernel, double qxx, double qxy, double qyy, int half_width)
    : half_width_(half_width) {
    const int window = 2 * half_width;
    pitch_ = window == 4 ? 4 : (window + 7) / 8 * 8;
    entry_size_ = size_t(window) * pitch_;
    const int fit = int(std::sqrt(double(kTargetBytes) / (entry_size_ * sizeof(float)))) - 1;
    phases_ = window == 4 ? kPhases4x4 : std::clamp(fit, kFewestPhases, kMostPhases);
    values_.assign(size_t(phases_ + 1) * (phases_ + 1) * entry_size_, 0.0f);
    for (int py = 0; py <= phases_; ++py)
        for (int px = 0; px <= phases_; ++px) {
            const double fx = double(px) / phases_, fy = double(py) / phases_;
            float* w = values_.data() + (size_t(py) * (phases_ + 1) + px) * entry_size_;
            for (int j = 0; j < window; ++j)
                for (int i = 0; i < window; ++i) {
                    const double dx = i - (half_width - 1) - fx, dy = j - (half_width - 1) - fy;
                    const double rho2 = qxx * dx * dx + 2.0 * qxy * dx * dy + qyy * dy * dy;
                    if (rho2 < kernel.radius() * kernel.radius())
                        w[size_t(j) * pitch_ + i] = float(kernel.line_integral(std::sqrt(std::max(0.0, rho2))));
                }
        }
}

}  // namespace pcvr
