/// @file preintegration.cpp
/// @brief The pre-integration table of a transfer function: its integral functions, their cache with the
/// function, and the mean over a stretch of ray from its two end densities.
#include "shaded/classify/preintegration.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "shaded/classify/table_entries.h"

namespace pcvr {

namespace {
std::atomic<uint64_t> built_count{0};

/// Per entry, the values of C channels and their running integral over the entries (trapezoids: the exact
/// integral of the piecewise-linear interpolation), the last entry repeated beyond the end.
template <class Entry, class Values>
std::vector<Entry> integrate(int entries, Values values) {
    constexpr int C = int(sizeof(Entry::value) / sizeof(double));
    std::vector<Entry> out(size_t(entries) + 2);
    for (int e = 0; e <= entries; ++e) values(e, out[size_t(e)].value);
    out[size_t(entries) + 1] = out[size_t(entries)];
    for (int c = 0; c < C; ++c) {
        out[0].integral[c] = 0;
        for (size_t e = 1; e < out.size(); ++e)
            out[e].integral[c] = out[e - 1].integral[c] + 0.5 * (out[e - 1].value[c] + out[e].value[c]);
    }
    return out;
}

}  // namespace

PreintegrationTable::PreintegrationTable(const TransferFunction& tf)
    : density_(tf.density), rgba_(tf.rgba), emission_points_(tf.emission) {
    tf.validate();
    const TableEntries at = table_entries(tf);
    first_ = at.first;
    scale_ = 1.0 / at.step;
    absorption_ = integrate<Entry<4>>(kEntries, [&](int e, double (&v)[4]) {
        const std::array<double, 4>& p = at.rgba[size_t(e)];
        v[0] = -std::log1p(-p[3]);  // extinction times unit_distance
        for (int c = 0; c < 3; ++c) v[c + 1] = v[0] * p[c];
    });
    if (tf.has_emission())
        emission_ = integrate<Entry<3>>(kEntries, [&](int e, double (&v)[3]) {
            for (int c = 0; c < 3; ++c) v[c] = at.emission[size_t(e)][c];
        });
    ++built_count;
}

uint64_t PreintegrationTable::tables_built() { return built_count.load(); }

size_t PreintegrationTable::bytes() const {
    return sizeof(*this) + absorption_.size() * sizeof(Entry<4>) + emission_.size() * sizeof(Entry<3>) +
           density_.size() * sizeof(double) + rgba_.size() * sizeof(rgba_[0]) + emission_points_.size() * sizeof(emission_points_[0]);
}

bool PreintegrationTable::made_from(const TransferFunction& tf) const {
    return tf.density == density_ && tf.rgba == rgba_ && tf.emission == emission_points_;
}

std::shared_ptr<const PreintegrationTable> PreintegrationTable::of(const TransferFunction& tf, bool* built) {
    auto build = [&] {
        if (built) *built = true;
        return std::make_shared<const PreintegrationTable>(tf);
    };
    if (!tf.tables) return build();
    std::lock_guard<std::mutex> lock(tf.tables->mutex);
    std::shared_ptr<const PreintegrationTable>& kept = tf.tables->preintegration;
    if (!kept || !kept->made_from(tf)) kept = build();
    return kept;
}

/// The integral of each channel from entry 0 to x (in entries, any real): within the table the exact
/// integral of the linear interpolation, beyond its ends the end values times the distance.
template <int C>
void PreintegrationTable::integral_at(const std::vector<Entry<C>>& table, double x, double (&out)[C]) {
    if (x <= 0) {
        for (int c = 0; c < C; ++c) out[c] = x * table[0].value[c];
        return;
    }
    if (x >= kEntries) {
        const Entry<C>& end = table[size_t(kEntries)];
        for (int c = 0; c < C; ++c) out[c] = end.integral[c] + (x - kEntries) * end.value[c];
        return;
    }
    const size_t i = size_t(x);
    const double f = x - double(i);
    const Entry<C>&a = table[i], &b = table[i + 1];
    for (int c = 0; c < C; ++c) out[c] = a.integral[c] + f * (a.value[c] + 0.5 * f * (b.value[c] - a.value[c]));
}

template <int C>
void PreintegrationTable::mean_over(const std::vector<Entry<C>>& table, double x0, double x1, double (&out)[C]) {
    double lo[C], hi[C];
    integral_at(table, x0, lo);
    integral_at(table, x1, hi);
    const double per = 1.0 / (x1 - x0);
    for (int c = 0; c < C; ++c) out[c] = (hi[c] - lo[c]) * per;
}

PreintegrationTable::Half PreintegrationTable::half(double x0, double x1) const {
    // A half of (nearly) no length is its point: widened to a thousandth of an entry, the means are its values
    // to double's precision and the divisions stay finite.
    if (std::abs(x1 - x0) < 1e-3) {
        const double c = 0.5 * (x0 + x1);
        x0 = c - 5e-4, x1 = c + 5e-4;
    }
    Half out{};
    mean_over(absorption_, x0, x1, out.absorption);
    if (has_emission()) mean_over(emission_, x0, x1, out.emission);
    return out;
}

PreintegrationTable::Slabs PreintegrationTable::operator()(const ClassificationTable& point, float8 front, float8 middle,
                                                           float8 back, int8x lanes) const {
    // Within one entry the functions are linear (up to one kink): the point table at the mean density is the mean.
    const float8 mean = 0.25f * (front + back) + 0.5f * middle;
    Slabs out{point(mean), {}};
    if (has_emission()) out.glow = point.emission(mean);
    const float8 entries_apart = (max8(max8(front, back), middle) - min8(min8(front, back), middle)) * float(scale_);
    const uint32_t wide = lane_mask(lanes & (entries_apart >= 1.0f));
    if (!wide) return out;
    const double per_unit = point.per_unit_distance();
    auto entry = [&](float density) { return (double(density) - first_) * scale_; };
    for (int l = 0; l < 8; ++l) {
        if (!((wide >> l) & 1)) continue;
        // Two linear halves through the reconstruction's middle: a thin peak between the ends (a one-voxel
        // bone) is followed, where one straight line from end to end would cut under it.
        const double xm = entry(middle[l]);
        const Half a = half(entry(front[l]), xm), b = half(xm, entry(back[l]));
        const double absorption = a.absorption[0] + b.absorption[0];  // twice the mean: each half is half the stretch
        const bool absorbs = absorption > 0;
        out.light.extinction[l] = float(std::min(0.5 * absorption * per_unit, 1e30));
        out.light.red[l] = absorbs ? float((a.absorption[1] + b.absorption[1]) / absorption) : 0.0f;
        out.light.green[l] = absorbs ? float((a.absorption[2] + b.absorption[2]) / absorption) : 0.0f;
        out.light.blue[l] = absorbs ? float((a.absorption[3] + b.absorption[3]) / absorption) : 0.0f;
        if (has_emission()) {
            out.glow.red[l] = float(0.5 * (a.emission[0] + b.emission[0]));
            out.glow.green[l] = float(0.5 * (a.emission[1] + b.emission[1]));
            out.glow.blue[l] = float(0.5 * (a.emission[2] + b.emission[2]));
        }
    }
    return out;
}

}  // namespace pcvr
