#include "pcvr/transfer_function.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "pcvr/errors.h"
#include "shaded/classify/table_entries.h"

namespace pcvr {

void TransferFunction::validate() const {
    const std::string what = "TransferFunction: ";
    if (density.empty()) throw InvalidArgument(what + "needs at least one control point");
    if (density.size() != rgba.size())
        throw InvalidArgument(what + std::to_string(density.size()) + " densities but " + std::to_string(rgba.size()) +
                              " rgba values (one [r, g, b, a] per density)");
    for (size_t i = 0; i < density.size(); ++i) {
        const std::string point = "control point " + std::to_string(i);
        if (!std::isfinite(density[i])) throw InvalidArgument(what + point + ": density is not finite");
        if (i > 0 && !(density[i] > density[i - 1]))
            throw InvalidArgument(what + "densities must increase (" + point + ": " + std::to_string(density[i]) +
                                  " after " + std::to_string(density[i - 1]) + ")");
        for (int c = 0; c < 4; ++c)
            if (!std::isfinite(rgba[i][c])) throw InvalidArgument(what + point + ": rgba is not finite");
        if (rgba[i][0] < 0 || rgba[i][1] < 0 || rgba[i][2] < 0)
            throw InvalidArgument(what + point + ": colours must not be negative");
        if (rgba[i][3] < 0 || rgba[i][3] > 1) throw InvalidArgument(what + point + ": opacity must lie in [0, 1]");
    }
    if (!(unit_distance >= 0) || !std::isfinite(unit_distance))
        throw InvalidArgument(what + "unit_distance must be positive (or None for the voxel spacing)");
    if (gradient.size() != gradient_opacity.size())
        throw InvalidArgument(what + std::to_string(gradient.size()) + " gradient magnitudes but " +
                              std::to_string(gradient_opacity.size()) + " gradient_opacity values (one per magnitude)");
    for (size_t i = 0; i < gradient.size(); ++i) {
        const std::string point = "gradient point " + std::to_string(i);
        if (!std::isfinite(gradient[i]) || gradient[i] < 0)
            throw InvalidArgument(what + point + ": the gradient magnitude must be finite and not negative");
        if (i > 0 && !(gradient[i] > gradient[i - 1]))
            throw InvalidArgument(what + "gradient magnitudes must increase (" + point + ": " + std::to_string(gradient[i]) +
                                  " after " + std::to_string(gradient[i - 1]) + ")");
        if (!(gradient_opacity[i] >= 0 && gradient_opacity[i] <= 1))
            throw InvalidArgument(what + point + ": gradient_opacity must lie in [0, 1]");
    }
    if (!emission.empty() && emission.size() != density.size())
        throw InvalidArgument(what + std::to_string(density.size()) + " densities but " + std::to_string(emission.size()) +
                              " emission values (one [r, g, b] per density, or none)");
    for (size_t i = 0; i < emission.size(); ++i)
        for (double e : emission[i])
            if (!std::isfinite(e) || e < 0)
                throw InvalidArgument(what + "control point " + std::to_string(i) + ": emission must be finite and not negative");
}

namespace {
/// The gradient opacity factor at |gradient| m: piecewise linear, the end values beyond the ends.
double gradient_factor_at(const TransferFunction& tf, double m) {
    const auto& g = tf.gradient;
    const auto& o = tf.gradient_opacity;
    if (m <= g.front()) return o.front();
    if (m >= g.back()) return o.back();
    const size_t k = size_t(std::upper_bound(g.begin(), g.end(), m) - g.begin());  // g[k - 1] <= m < g[k]
    return o[k - 1] + (m - g[k - 1]) / (g[k] - g[k - 1]) * (o[k] - o[k - 1]);
}
}  // namespace

TableEntries table_entries(const TransferFunction& tf) {
    TableEntries out;
    const int n = ClassificationTable::kEntries;
    const double first = tf.density.front(), last = tf.density.back();
    out.first = first;
    out.step = last > first ? (last - first) / n : 1.0;
    out.rgba.resize(n + 1);
    if (tf.has_emission()) out.emission.resize(n + 1);
    size_t segment = 0;  // control points segment, [segment, segment + 1]
    for (int e = 0; e <= n; ++e) {
        const double d = first + e * out.step;
        while (segment + 1 < tf.density.size() && tf.density[segment + 1] < d) ++segment;
        std::array<double, 4> v = tf.rgba[segment];
        std::array<double, 3> glow = tf.has_emission() ? tf.emission[segment] : std::array<double, 3>{};
        if (segment + 1 < tf.density.size() && d > tf.density[segment]) {
            const double t = std::min(1.0, (d - tf.density[segment]) / (tf.density[segment + 1] - tf.density[segment]));
            for (int c = 0; c < 4; ++c) v[c] += t * (tf.rgba[segment + 1][c] - v[c]);
            if (tf.has_emission())
                for (int c = 0; c < 3; ++c) glow[c] += t * (tf.emission[segment + 1][c] - glow[c]);
        }
        v[3] = std::min(v[3], kMostOpacity);
        out.rgba[size_t(e)] = v;
        if (tf.has_emission()) out.emission[size_t(e)] = glow;
    }
    return out;
}

ClassificationTable::ClassificationTable(const TransferFunction& tf, double unit_distance) {
    tf.validate();
    if (!(unit_distance > 0) || !std::isfinite(unit_distance))
        throw InvalidArgument("TransferFunction: unit_distance must be positive");
    const TableEntries at = table_entries(tf);
    const double first = at.first, step = at.step;
    first_ = float(first);
    scale_ = float(1.0 / step);
    per_unit_distance_ = float(std::min(1.0 / unit_distance, 1e30));

    entries_.resize(4 * size_t(kEntries + 2));
    extinction_.resize(kEntries + 2);
    if (tf.has_emission())
        for (auto* channel : {&emit_red_, &emit_green_, &emit_blue_}) channel->resize(kEntries + 2);
    for (int e = 0; e <= kEntries; ++e) {
        const std::array<double, 4>& v = at.rgba[size_t(e)];
        const double opacity = v[3];
        // Capped where a unit_distance of 1e-300 would make it infinite: opaque in any sample anyway.
        extinction_[e] = float(std::min(-std::log1p(-opacity) / unit_distance, 1e30));
        for (int c = 0; c < 3; ++c) entries_[4 * size_t(e) + c] = float(v[c]);
        entries_[4 * size_t(e) + 3] = extinction_[e];
        if (tf.has_emission()) {
            const std::array<double, 3>& glow = at.emission[size_t(e)];
            emit_red_[e] = float(glow[0]), emit_green_[e] = float(glow[1]), emit_blue_[e] = float(glow[2]);
        }
        if (tf.has_gradient_opacity()) opacity_.push_back(float(opacity));
    }
    for (auto* channel : {&extinction_, &emit_red_, &emit_green_, &emit_blue_})
        if (!channel->empty()) (*channel)[kEntries + 1] = (*channel)[kEntries];
    std::copy_n(entries_.begin() + 4 * kEntries, 4, entries_.begin() + 4 * (kEntries + 1));
    if (tf.has_gradient_opacity()) {
        opacity_.push_back(opacity_.back());
        const double g0 = tf.gradient.front(), g1 = tf.gradient.back();
        const double g_step = g1 > g0 ? (g1 - g0) / kGradientEntries : 1.0;
        gradient_first_ = float(g0);
        gradient_scale_ = float(1.0 / g_step);
        for (int e = 0; e <= kGradientEntries; ++e) gradient_factor_.push_back(float(gradient_factor_at(tf, g0 + e * g_step)));
        gradient_factor_.push_back(gradient_factor_.back());
    }

    // Visible: absorbs or emits (an emitting density with no opacity still adds light).
    auto visible = [&](int e) {
        return extinction_[e] > 0 || (has_emission() && (emit_red_[e] > 0 || emit_green_[e] > 0 || emit_blue_[e] > 0));
    };
    next_opaque_.resize(kEntries + 2);
    int next = kEntries + 2;
    for (int e = kEntries + 1; e >= 0; --e) {
        if (visible(e)) next = e;
        next_opaque_[e] = next;
    }
    // Interpolation reaches one entry beyond the first and last visible ones; the ends extend forever.
    int last_opaque = -1;
    for (int e = 0; e <= kEntries; ++e)
        if (visible(e)) last_opaque = e;
    if (last_opaque < 0) {
        opaque_from_ = INFINITY, opaque_to_ = -INFINITY;
    } else {
        const int first_opaque = next_opaque_[0];
        opaque_from_ = first_opaque == 0 ? -INFINITY : float(first + (first_opaque - 1) * step);
        opaque_to_ = last_opaque == kEntries ? INFINITY : float(first + (last_opaque + 1) * step);
    }
}

bool ClassificationTable::transparent(double lo, double hi) const {
    // Entries floor(lo) .. ceil(hi) bound every interpolated value in between.
    auto index = [&](double d) { return std::clamp((d - double(first_)) * double(scale_), 0.0, double(kEntries)); };
    const int first = int(std::floor(index(lo))), last = int(std::ceil(index(hi)));
    return next_opaque_[first] > last;
}

}  // namespace pcvr
