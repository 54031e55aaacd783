/// @file phase_table.h
/// @brief A voxel's whole footprint window, tabulated per sub-node phase, for orthographic splats.
///
/// When every voxel's footprint has the same shape in node units (orthographic views), the weights
/// of the window of taps around a voxel depend only on where its centre falls inside its node.
/// Tabulating them at (phases + 1)^2 phases and interpolating bilinearly between the four nearest
/// turns a splat into plain loads, a blend and row updates, with no per-tap table lookups (gathers
/// cost about a cycle per lane on many CPUs). Interpolation keeps the error second order (for PCVR's
/// window 1e-4 of the peak weight RMS, 7e-4 at worst at the kernel's truncated rim) and, unlike rounding to the nearest phase, free of the coherent sub-pixel shift that
/// axis-aligned views would otherwise show.
///
/// PCVR's window is 4 x 4 nodes with 32 phases per node; regular splatting at magnification m has a
/// window of about 4m x 4m pixels, where fewer phases per pixel suffice because the footprint is
/// smooth at that scale. The number of phases is chosen to keep the table near 256 KiB.
#pragma once

#include <algorithm>
#include <vector>

#include "pcvr/kernel.h"

namespace pcvr {

class PhaseFootprintTable {
public:
    /// Largest half-width (in nodes) worth tabulating; wider footprints use per-tap lookups.
    static constexpr int kMaxHalfWidth = 32;

    /// The footprint rho^2 = qxx dx^2 + 2 qxy dx dy + qyy dy^2 (node units) of `kernel`, for a window
    /// of 2 * half_width taps per axis (half_width >= the footprint's extent in nodes).
    PhaseFootprintTable(const Kernel& kernel, double qxx, double qxy, double qyy, int half_width);
    /// The same from the kernel's FootprintTable, as perspective footprints take their taps (src/splat/
    /// phase_table_cache.h): a table in some 0.1 ms instead of the analytic line integral's millisecond.
    PhaseFootprintTable(const FootprintTable& footprint, double qxx, double qxy, double qyy, int half_width);

    /// Bilinear spreading (Westenberg-Roerdink) in the same form: a 2 x 2 window with one phase per
    /// node, whose window at each corner phase holds 1 on the node the centre sits on. Interpolating
    /// between the four corners spreads a voxel bilinearly over its 2 x 2 nearest nodes.
    static PhaseFootprintTable bilinear_spread();

    /// A footprint narrower than a pixel averaged over each pixel's box (src/splat/pixel_prefilter.h), for
    /// footprints whose axes are the node axes: per axis a Gaussian of standard deviation sigma (nodes)
    /// convolved with a box of half-width `half_pixel` (nodes), each axis's taps normalised to sum to
    /// one (times a voxel's mass, the window then holds all of it).
    static PhaseFootprintTable pixel_averaged(double sigma_x, double sigma_y, double half_pixel, int half_width);
    bool is_bilinear_spread() const { return phases_ == 1 && half_width_ == 1; }

    int half_width() const { return half_width_; }
    int window() const { return 2 * half_width_; }
    /// Floats per tabulated row: the window rounded up to whole 8-lane vectors (4 for the 4 x 4 window).
    int pitch() const { return pitch_; }
    int phases() const { return phases_; }
    /// Floats per tabulated phase (window rows x pitch), and the table: (phases + 1)^2 of them, x fastest.
    size_t entry_size() const { return entry_size_; }
    const float* data() const { return values_.data(); }

    /// The four tabulated phases around a centre and their bilinear blend weights.
    struct Blend {
        const float* entry[4];  ///< window rows x pitch weights each: (px, py), (px + 1, py), (px, py + 1), (px + 1, py + 1)
        float coeff[4];
    };

    /// For taps (c - h + 1 + i, r - h + 1 + j), i, j in [0, window), h = half_width, of a centre at
    /// (c + fx, r + fy) with integer c, r and fx, fy in [0, 1]. (The batched splat repeats this
    /// arithmetic for eight centres at once: src/splat/phase_splat.cpp, prepare.)
    Blend blend(float fx, float fy) const {
        const float sx = fx * phases_, sy = fy * phases_;
        const int px = std::min(phases_ - 1, int(sx)), py = std::min(phases_ - 1, int(sy));
        const float ax = sx - px, ay = sy - py;
        const float* e = values_.data() + (size_t(py) * (phases_ + 1) + px) * entry_size_;
        const size_t row = size_t(phases_ + 1) * entry_size_;
        return {{e, e + entry_size_, e + row, e + row + entry_size_},
                {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay}};
    }

    /// Phases per node of PCVR's 4 x 4 window (the batched splat knows its sizes at compile time).
    static constexpr int kPhases4x4 = 32;

    /// Whether interpolating between this table's phases stands for a footprint whose narrowest standard
    /// deviation is `sigma` nodes. A sampled footprint's weights are off by about 1 / (8 (sigma P)^2) of its
    /// peak with P phases a node: beyond 1e-3 (sigma P < 11: minified views, elongated footprints in wide
    /// windows of few phases) footprints go per tap; a 1 x 1 image at 26 voxels per pixel was 1.3% off,
    /// isolated voxels at 0.5 pixels per voxel 0.7%. A pixel-averaged one is the Gaussian convolved with the
    /// pixel's box, whose weights bend far less within a phase: at 32 phases its largest error was 7.5e-4 of
    /// the peak at sigma P = 6.4 and 4.9e-4 at 11 (a Gaussian's: 1.05e-3 at 11), so it resolves from 6.4 on
    /// (0.2 nodes: magnification 0.34 with PCVR's kernel).
    bool resolves(double sigma, bool pixel_averaged = false) const {
        return sigma * phases_ >= (pixel_averaged ? kPixelAveragedSigmaPhases : 11.0);
    }
    static constexpr double kPixelAveragedSigmaPhases = 6.4;

private:
    PhaseFootprintTable(int half_width, int phases);

    int half_width_, pitch_, phases_;
    size_t entry_size_;
    std::vector<float> values_;
};

/// A footprint narrower than a pixel averaged over each pixel's box along the node axes (src/splat/
/// pixel_prefilter.h), kept as what it is: the product of an x row and a y column of weights, each tabulated
/// per phase (64 a node, interpolated linearly) and normalised to sum to one. Where PhaseFootprintTable holds
/// the whole window at every pair of phases (209 KB for a 6 x 6 window), this holds two rows of eight floats a
/// phase (4 KB): perspective blocks, each with the table of its own footprint, find theirs in L1, and a window
/// costs a row of eight lanes per tap row. Windows of at most kMaxWindow taps a side.
class SeparableFootprintTable {
public:
    static constexpr int kPhases = 64;
    static constexpr int kMaxWindow = 8;  ///< one 8-lane vector a row

    /// Standard deviations sigma_x, sigma_y and the box's half-width half_pixel in nodes; half_width >= the
    /// footprint's reach in nodes (at most kMaxWindow / 2).
    SeparableFootprintTable(double sigma_x, double sigma_y, double half_pixel, int half_width);

    int half_width() const { return half_width_; }
    int window() const { return 2 * half_width_; }
    /// kMaxWindow weights of the x row (y column) at phase p in [0, kPhases], zero past the window.
    const float* x(int p) const { return x_.data() + size_t(p) * kMaxWindow; }
    const float* y(int p) const { return y_.data() + size_t(p) * kMaxWindow; }
    /// As PhaseFootprintTable::resolves for pixel-averaged footprints, `sigma` the narrower one (nodes).
    static bool resolves(double sigma) { return sigma * kPhases >= PhaseFootprintTable::kPixelAveragedSigmaPhases; }

private:
    int half_width_;
    std::vector<float> x_, y_;
};

}  // namespace pcvr
