/// @file value_levels.h
/// @brief Values as 8-bit levels rounded outwards: how the range tables (Grid::voxel_value_ranges, the
/// prefiltered lattice's brick ranges) keep a range in two bytes that still holds the true one.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace pcvr {

struct ValueLevels {
    double lowest = 0, step = 1;

    /// 255 steps over [lowest, highest], the top one reaching highest.
    static ValueLevels spanning(double lowest, double highest) {
        ValueLevels l{lowest, highest > lowest ? (highest - lowest) / 255.0 : 1.0};
        while (l.value(255) < highest) l.step = std::nextafter(l.step, INFINITY);
        return l;
    }
    double value(int level) const { return lowest + level * step; }
    /// The highest level at or below v, and the lowest at or above it.
    uint8_t below(double v) const {
        int q = int(std::clamp(std::floor((v - lowest) / step), 0.0, 255.0));
        while (q > 0 && value(q) > v) --q;  // at most once: the division rounds by less than a level
        return uint8_t(q);
    }
    uint8_t above(double v) const {
        int q = int(std::clamp(std::ceil((v - lowest) / step), 0.0, 255.0));
        while (q < 255 && value(q) < v) ++q;
        return uint8_t(q);
    }
};

}  // namespace pcvr
