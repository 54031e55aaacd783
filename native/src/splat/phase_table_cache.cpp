#include "splat/phase_table_cache.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>

#include "pcvr/math.h"
#include "view/footprint_limits.h"
#include "view/level_of_detail.h"

namespace pcvr {

namespace {

constexpr double kLogSteps = 64;          // lattice points per octave of a form's diagonal or a standard deviation
constexpr double kCorrelationSteps = 128;  // of qxy / sqrt(qxx qyy), in [-1, 1]
/// Beyond this many tables (about 18 MB of 4 x 4 ones) the cache starts again.
constexpr size_t kMostTables = 256;
/// A pixel-averaged key's last coordinate: the level of detail plus this many times the stride on the lattice.
constexpr int32_t kLevels = 64;

enum Kind : int32_t { kSampled = 1, kPixelAveraged = 2 };

int32_t on_lattice(double value, double steps) { return clamp_to_int(std::round(value * steps), -(1 << 30), 1 << 30); }

CachedPhaseTable sampled(const PhaseTableKey& key, const Kernel& kernel) {
    if (!kernel.smooth_footprint()) return {};
    const double qxx = std::exp2(key.lattice[1] / kLogSteps), qyy = std::exp2(key.lattice[2] / kLogSteps);
    const double qxy = key.lattice[3] / kCorrelationSteps * std::sqrt(qxx * qyy);
    const double det = qxx * qyy - qxy * qxy;
    if (!(det > 0)) return {};
    const double radius = kernel.radius();
    const double reach = std::max(radius * std::sqrt(qyy / det), radius * std::sqrt(qxx / det));
    const int half_width = clamp_to_int(std::ceil(reach - 1e-4), 0, PhaseFootprintTable::kMaxHalfWidth + 1);
    if (half_width > PhaseFootprintTable::kMaxHalfWidth) return {};
    auto table = std::make_shared<PhaseFootprintTable>(FootprintTable::of(kernel), qxx, qxy, qyy, std::max(half_width, 2));
    // The narrowest standard deviation in nodes: the kernel's over the form's largest eigenvalue.
    const double half_trace = 0.5 * (qxx + qyy), half_difference = 0.5 * (qxx - qyy);
    const double largest = half_trace + std::sqrt(half_difference * half_difference + qxy * qxy);
    if (!table->resolves(std::sqrt(kernel.variance() / largest))) return {};
    return {std::move(table), det};
}

CachedPhaseTable pixel_averaged(const PhaseTableKey& key, const Kernel& kernel) {
    const double sigma_x = std::exp2(key.lattice[1] / kLogSteps), sigma_y = std::exp2(key.lattice[2] / kLogSteps);
    const double variance = level_kernel_variance(kernel.variance(), key.lattice[3] % kLevels);
    const double half_pixel = kPrefilterReach / std::exp2((key.lattice[3] / kLevels) / kLogSteps);  // nodes
    const double reach = kernel.radius() * std::max(sigma_x, sigma_y) / std::sqrt(variance) + half_pixel;
    const int half_width = clamp_to_int(std::ceil(reach - 1e-4), 0, PhaseFootprintTable::kMaxHalfWidth + 1);
    if (half_width > PhaseFootprintTable::kMaxHalfWidth) return {};
    if (2 * half_width <= SeparableFootprintTable::kMaxWindow) {
        if (!SeparableFootprintTable::resolves(std::min(sigma_x, sigma_y))) return {};
        CachedPhaseTable made;
        made.separable = std::make_shared<SeparableFootprintTable>(sigma_x, sigma_y, half_pixel, std::max(half_width, 2));
        return made;
    }
    auto table = std::make_shared<PhaseFootprintTable>(
        PhaseFootprintTable::pixel_averaged(sigma_x, sigma_y, half_pixel, std::max(half_width, 2)));
    if (!table->resolves(std::min(sigma_x, sigma_y), true)) return {};
    return {std::move(table), 0.0};
}

}  // namespace

struct PhaseTableCache::Impl {
    std::mutex mutex;
    std::map<std::array<int32_t, 4>, CachedPhaseTable> tables;
};

PhaseTableCache& PhaseTableCache::instance() {
    static PhaseTableCache cache;
    static std::once_flag made;
    std::call_once(made, [] { cache.impl_ = std::make_shared<Impl>(); });
    return cache;
}

PhaseTableKey PhaseTableCache::footprint_key(const Kernel& kernel, double qxx, double qxy, double qyy) {
    const double correlation = qxy / std::sqrt(qxx * qyy);
    return {{kSampled * 16 + int32_t(kernel.shape()), on_lattice(std::log2(qxx), kLogSteps), on_lattice(std::log2(qyy), kLogSteps),
             on_lattice(std::isfinite(correlation) ? correlation : 0.0, kCorrelationSteps)}};
}

PhaseTableKey PhaseTableCache::pixel_averaged_key(const Kernel& kernel, int level, double sigma_x, double sigma_y,
                                                  double stride) {
    const int32_t strides = clamp_to_int(std::round(std::log2(std::max(stride, 1.0)) * kLogSteps), 0, (1 << 20));
    return {{kPixelAveraged * 16 + int32_t(kernel.shape()), on_lattice(std::log2(sigma_x), kLogSteps),
             on_lattice(std::log2(sigma_y), kLogSteps), std::clamp(level, 0, kLevels - 1) + kLevels * strides}};
}

CachedPhaseTable PhaseTableCache::get(const PhaseTableKey& key, const Kernel& kernel) {
    {
        std::lock_guard<std::mutex> lock(impl_->mutex);
        const auto it = impl_->tables.find(key.lattice);
        if (it != impl_->tables.end()) return it->second;
    }
    // Made outside the lock (a tenth of a millisecond); a worker that made the same one meanwhile wins.
    CachedPhaseTable made = key.lattice[0] / 16 == kSampled ? sampled(key, kernel) : pixel_averaged(key, kernel);
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->tables.size() >= kMostTables) impl_->tables.clear();
    return impl_->tables.emplace(key.lattice, std::move(made)).first->second;
}

}  // namespace pcvr
