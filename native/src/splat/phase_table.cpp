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

/// One axis of a pixel-averaged footprint (src/splat/pixel_prefilter.h) for a centre at phase f of its node:
/// a Gaussian of standard deviation sigma (nodes) integrated over the box of each of the window's taps
/// (half-width half_pixel nodes), normalised to sum to one.
void box_averaged_gaussian(double sigma, double half_pixel, double f, int half_width, double* w) {
    const double scale = 1.0 / (sigma * std::sqrt(2.0));
    double sum = 0;
    for (int i = 0; i < 2 * half_width; ++i) {
        const double d = i - (half_width - 1) - f;
        w[i] = 0.5 * (std::erf((d + half_pixel) * scale) - std::erf((d - half_pixel) * scale));
        sum += w[i];
    }
    for (int i = 0; i < 2 * half_width; ++i) w[i] = sum > 0 ? w[i] / sum : 0.0;
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
    std::vector<double> wx(window), wy(window);
    for (int py = 0; py <= t.phases_; ++py) {
        box_averaged_gaussian(sigma_y, half_pixel, double(py) / t.phases_, half_width, wy.data());
        for (int px = 0; px <= t.phases_; ++px) {
            box_averaged_gaussian(sigma_x, half_pixel, double(px) / t.phases_, half_width, wx.data());
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

namespace pcvr {

SeparableFootprintTable::SeparableFootprintTable(double sigma_x, double sigma_y, double half_pixel, int half_width)
    : half_width_(std::clamp(half_width, 1, kMaxWindow / 2)), x_(size_t(kPhases + 1) * kMaxWindow, 0.0f),
      y_(size_t(kPhases + 1) * kMaxWindow, 0.0f) {
    double w[kMaxWindow];
    for (int p = 0; p <= kPhases; ++p) {
        box_averaged_gaussian(sigma_x, half_pixel, double(p) / kPhases, half_width_, w);
        std::copy(w, w + window(), x_.begin() + size_t(p) * kMaxWindow);
        box_averaged_gaussian(sigma_y, half_pixel, double(p) / kPhases, half_width_, w);
        std::copy(w, w + window(), y_.begin() + size_t(p) * kMaxWindow);
    }
}

}  // namespace pcvr
