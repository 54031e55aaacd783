#include "splat/phase_table.h"

#include <algorithm>
#include <cmath>

namespace pcvr {

namespace {
constexpr size_t kTargetBytes = 256 * 1024;
constexpr int kMostPhases = PhaseFootprintTable::kPhases4x4;
constexpr int kFewestPhases = 4;

/// Floats per tabulated row: 4 for PCVR's window (two rows per vector), else whole 8-lane vectors.
int pitch_for(int window) { return window == 4 ? 4 : (window + 7) / 8 * 8; }

int phases_for(int half_width) {
    const int window = 2 * half_width;
    if (window == 4) return PhaseFootprintTable::kPhases4x4;
    const int fit = int(std::sqrt(double(kTargetBytes) / (double(window) * pitch_for(window) * sizeof(float)))) - 1;
    return std::clamp(fit, kFewestPhases, kMostPhases);
}
}  // namespace

PhaseFootprintTable::PhaseFootprintTable(int half_width, int phases)
    : half_width_(half_width), pitch_(pitch_for(2 * half_width)), phases_(phases) {
    entry_size_ = size_t(2 * half_width) * pitch_;
    values_.assign(size_t(phases_ + 1) * (phases_ + 1) * entry_size_, 0.0f);
}

PhaseFootprintTable PhaseFootprintTable::bilinear_spread() {
    PhaseFootprintTable t(1, 1);
    for (int py = 0; py <= 1; ++py)
        for (int px = 0; px <= 1; ++px) t.values_[(size_t(py) * 2 + px) * t.entry_size_ + size_t(py) * t.pitch_ + px] = 1.0f;
    return t;
}

PhaseFootprintTable PhaseFootprintTable::pixel_averaged(double sigma_x, double sigma_y, double half_pixel, int half_width) {
    PhaseFootprintTable t(half_width, phases_for(half_width));
    const int window = 2 * half_width;
    // One axis's weights for a centre at phase f: the Gaussian's mass over each tap's box.
    auto axis = [&](double sigma, double f, std::vector<double>& w) {
        const double scale = 1.0 / (sigma * std::sqrt(2.0));
        double sum = 0;
        for (int i = 0; i < window; ++i) {
            const double d = i - (half_width - 1) - f;
            w[i] = 0.5 * (std::erf((d + half_pixel) * scale) - std::erf((d - half_pixel) * scale));
            sum += w[i];
        }
        for (double& v : w) v = sum > 0 ? v / sum : 0.0;
    };
    std::vector<double> wx(window), wy(window);
    for (int py = 0; py <= t.phases_; ++py) {
        axis(sigma_y, double(py) / t.phases_, wy);
        for (int px = 0; px <= t.phases_; ++px) {
            axis(sigma_x, double(px) / t.phases_, wx);
            float* w = t.values_.data() + (size_t(py) * (t.phases_ + 1) + px) * t.entry_size_;
            for (int j = 0; j < window; ++j)
                for (int i = 0; i < window; ++i) w[size_t(j) * t.pitch_ + i] = float(wx[i] * wy[j]);
        }
    }
    return t;
}

namespace {

/// Fills `t`'s phases with the footprint rho^2 = qxx dx^2 + 2 qxy dx dy + qyy dy^2 of `profile(rho^2)`, zero
/// from `radius2` on.
template <class Profile>
void tabulate(std::vector<float>& values, int half_width, int phases, int pitch, size_t entry_size, double qxx, double qxy,
              double qyy, double radius2, Profile profile) {
    const int window = 2 * half_width;
    for (int py = 0; py <= phases; ++py)
        for (int px = 0; px <= phases; ++px) {
            const double fx = double(px) / phases, fy = double(py) / phases;
            float* w = values.data() + (size_t(py) * (phases + 1) + px) * entry_size;
            for (int j = 0; j < window; ++j)
                for (int i = 0; i < window; ++i) {
                    const double dx = i - (half_width - 1) - fx, dy = j - (half_width - 1) - fy;
                    const double rho2 = qxx * dx * dx + 2.0 * qxy * dx * dy + qyy * dy * dy;
                    if (rho2 < radius2) w[size_t(j) * pitch + i] = profile(std::max(0.0, rho2));
                }
        }
}

}  // namespace

PhaseFootprintTable::PhaseFootprintTable(const Kernel& kernel, double qxx, double qxy, double qyy, int half_width)
    : PhaseFootprintTable(half_width, phases_for(half_width)) {
    tabulate(values_, half_width, phases_, pitch_, entry_size_, qxx, qxy, qyy, kernel.radius() * kernel.radius(),
             [&](double rho2) { return float(kernel.line_integral(std::sqrt(rho2))); });
}

PhaseFootprintTable::PhaseFootprintTable(const FootprintTable& footprint, double qxx, double qxy, double qyy, int half_width)
    : PhaseFootprintTable(half_width, phases_for(half_width)) {
    tabulate(values_, half_width, phases_, pitch_, entry_size_, qxx, qxy, qyy, footprint.radius2(),
             [&](double rho2) { return footprint.at_rho2(float(rho2)); });
}

}  // namespace pcvr
