/// @file brick_visibility.h
/// @brief Which bricks of a PrefilteredLattice may be visible, per visible density range, kept with the lattice.
///
/// Sampled sheets skip the values that nothing visible reads by a bit per lattice brick (SheetSampler): set where
/// the brick's value range, 0 included, meets the densities a transfer function shows. The bits depend only on
/// that span, the grid's density scale and its background, not on the camera or the lights, so they are made
/// once per span and kept here: viewport redraws, camera paths and light sweeps of one transfer function reuse
/// them (for the 256^3 phantom's lattice, 2.2M bricks, a few milliseconds a render). Memory: a bit per brick of
/// 2^3 elements, 1/256 of the lattice's values, for each of at most kEntries pairs of a span and a range set.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

namespace pcvr {

class BrickVisibilityCache {
public:
    using Bits = std::vector<uint32_t>;
    /// What the bits depend on: the span of densities that may be visible (ClassificationTable::visible_span),
    /// how lattice values become densities, and which of the lattice's range sets they test (its reach).
    struct Key {
        float visible_from, visible_to, density_scale, background;
        int range_reach;
        bool operator==(const Key& o) const {
            return visible_from == o.visible_from && visible_to == o.visible_to && density_scale == o.density_scale &&
                   background == o.background && range_reach == o.range_reach;
        }
    };
    /// Spans kept (two range sets each); the least recently used goes first.
    static constexpr size_t kEntries = 16;

    /// The bits for `key`, made by `build` on the first request. Thread-safe: concurrent renders of one
    /// lattice wait for each other's build rather than building twice. `built` says whether this call built them.
    std::shared_ptr<const Bits> get(const Key& key, const std::function<Bits()>& build, bool& built) {
        std::lock_guard<std::mutex> lock(mutex_);
        for (size_t i = 0; i < entries_.size(); ++i)
            if (entries_[i].key == key) {
                Entry hit = entries_[i];  // to the back: most recently used
                entries_.erase(entries_.begin() + long(i));
                entries_.push_back(hit);
                built = false;
                return hit.bits;
            }
        if (entries_.size() == kEntries) entries_.erase(entries_.begin());
        entries_.push_back({key, std::make_shared<const Bits>(build())});
        built = true;
        return entries_.back().bits;
    }

private:
    struct Entry {
        Key key;
        std::shared_ptr<const Bits> bits;
    };
    std::mutex mutex_;
    std::vector<Entry> entries_;
};

}  // namespace pcvr
