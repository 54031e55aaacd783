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
    second_.resize(absorption_.size());
    for (size_t e = 1; e < absorption_.size(); ++e)  // K is quadratic within an entry: its exact integral
        second_[e] = second_[e - 1] + (absorption_[e - 1].integral[0] + absorption_[e].integral[0]) / 2 -
                     (absorption_[e].value[0] - absorption_[e - 1].value[0]) / 12;
    if (tf.has_emission())
        emission_ = integrate<Entry<3>>(kEntries, [&](int e, double (&v)[3]) {
            for (int c = 0; c < 3; ++c) v[c] = at.emission[size_t(e)][c];
        });
    ++built_count;
}

uint64_t PreintegrationTable::tables_built() { return built_count.load(); }

size_t PreintegrationTable::bytes() const {
    return sizeof(*this) + absorption_.size() * sizeof(Entry<4>) + second_.size() * sizeof(double) + emission_.size() * sizeof(Entry<3>) +
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

double PreintegrationTable::second_integral_at(double x) const {
    if (x <= 0) return 0.5 * x * x * absorption_[0].value[0];
    if (x >= kEntries) {
        const double d = x - kEntries;
        const Entry<4>& end = absorption_[size_t(kEntries)];
        return second_[size_t(kEntries)] + d * end.integral[0] + 0.5 * d * d * end.value[0];
    }
    const size_t i = size_t(x);
    const double f = x - double(i);
    const Entry<4>&a = absorption_[i], &b = absorption_[i + 1];
    return second_[i] + f * (a.integral[0] + f * (a.value[0] / 2 + f * (b.value[0] - a.value[0]) / 6));
}

template <int C>
void PreintegrationTable::mean_over(const std::vector<Entry<C>>& table, double x0, double x1, double (&out)[C]) {
    double lo[C], hi[C];
    integral_at(table, x0, lo);
    integral_at(table, x1, hi);
    const double per = 1.0 / (x1 - x0);
    for (int c = 0; c < C; ++c) out[c] = (hi[c] - lo[c]) * per;
}

PreintegrationTable::Slabs PreintegrationTable::operator()(const ClassificationTable& point, float8 front, float8 back,
                                                           int8x lanes) const {
    // Within one entry the functions are linear (up to one kink): the point table at the middle is the mean.
    const float8 middle = 0.5f * (front + back);
    Slabs out{point(middle), {}, broadcast8(0.5f)};
    if (has_emission()) out.glow = point.emission(middle);
    const float8 entries_apart = abs8(back - front) * float(scale_);
    const uint32_t wide = lane_mask(lanes & (entries_apart >= 1.0f));
    if (!wide) return out;
    const double per_unit = point.per_unit_distance();
    for (int l = 0; l < 8; ++l) {
        if (!((wide >> l) & 1)) continue;
        const double x0 = (double(front[l]) - first_) * scale_, x1 = (double(back[l]) - first_) * scale_;
        double m[4];
        mean_over(absorption_, x0, x1, m);
        const bool absorbs = m[0] > 0;
        if (absorbs) {  // the extinction's first moment from the front, over (x1 - x0) times its integral m[0] (x1 - x0)
            double k1[4];
            integral_at(absorption_, x1, k1);
            const double moment = (x1 - x0) * k1[0] - (second_integral_at(x1) - second_integral_at(x0));
            out.centre[l] = float(std::clamp(moment / (m[0] * (x1 - x0) * (x1 - x0)), 0.0, 1.0));
        }
        out.light.extinction[l] = float(std::min(m[0] * per_unit, 1e30));
        out.light.red[l] = absorbs ? float(m[1] / m[0]) : 0.0f;
        out.light.green[l] = absorbs ? float(m[2] / m[0]) : 0.0f;
        out.light.blue[l] = absorbs ? float(m[3] / m[0]) : 0.0f;
        if (has_emission()) {
            double e[3];
            mean_over(emission_, x0, x1, e);
            out.glow.red[l] = float(e[0]), out.glow.green[l] = float(e[1]), out.glow.blue[l] = float(e[2]);
        }
    }
    return out;
}

}  // namespace pcvr
