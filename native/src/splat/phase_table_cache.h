/// @file phase_table_cache.h
/// @brief Phase tables for perspective footprints, shared by the blocks (and renders) whose footprints are alike.
///
/// An orthographic splat takes every voxel's window from one PhaseFootprintTable: loads and a blend, where a
/// footprint evaluated tap by tap costs a gather per eight taps and a window per voxel (perspective X-rays took
/// 4 to 7.5 times as long). Under perspective each voxel has its own footprint, but a block's voxels nearly share
/// one (its form changes by about 8 / D of itself across a block D voxels from the eye), and so do the blocks of
/// a depth band, whose stride follows their magnification. So a block takes the table of its centre's form,
/// rounded to a lattice of forms; each voxel keeps its own centre and its amplitude is scaled so that its mass is
/// its own footprint's. The tables are kept for later blocks and renders (a view moving in the viewport or an
/// animation meets the same forms again).
///
/// | footprint            | lattice                                                 | the voxel's weights are off by         |
/// |----------------------|---------------------------------------------------------|----------------------------------------|
/// | sampled (m >= 1)     | log2 qxx, log2 qyy in steps of 1/64; qxy / sqrt(qxx qyy) in steps of 1/128 | 0.2% of the peak at most (1.4 rho^2 e^(-1.4 rho^2) times 0.55%) |
/// | pixel-averaged (< 1), separable where its window fits 8 x 8 | log2 of each axis's standard deviation and of the stride in steps of 1/64 | a shift of 0.27% in its spread and in the pixel's width; its mass is exact (axes normalised) |
///
/// Pixel-averaged footprints have two coordinates (and tables of 4 KB where their window fits 8 x 8): every
/// perspective view takes them. Sampled ones have three, and a wide view meets hundreds of 70 KB tables.
///
/// Thread-safe: one mutex around the map, taken once per block (splat_blocks' workers memoise the last table).
#pragma once

#include <array>
#include <cstdint>
#include <memory>

#include "pcvr/kernel.h"
#include "splat/phase_table.h"

namespace pcvr {

/// A table and the footprint it holds.
struct CachedPhaseTable {
    std::shared_ptr<const PhaseFootprintTable> table;
    /// Sampled footprints: the form's determinant (node^4) the table holds, which a voxel's amplitude is
    /// scaled by (sqrt(table_det / det)) to keep its mass; pixel-averaged tables are normalised (0).
    double table_det = 0;
    /// Pixel-averaged footprints whose window is at most SeparableFootprintTable::kMaxWindow taps wide hold
    /// this instead of `table`.
    std::shared_ptr<const SeparableFootprintTable> separable;
};

/// Where on the lattice a form falls: what the cache is keyed by.
struct PhaseTableKey {
    std::array<int32_t, 4> lattice{};  ///< kind and kernel, then the three (or two) rounded coordinates
    bool operator==(const PhaseTableKey& o) const { return lattice == o.lattice; }
};

class PhaseTableCache {
public:
    /// The process's cache.
    static PhaseTableCache& instance();

    /// The key of a sampled footprint of `kernel` with form (qxx, qxy, qyy) in node units.
    static PhaseTableKey footprint_key(const Kernel& kernel, double qxx, double qxy, double qyy);
    /// The key of a pixel-averaged footprint of standard deviations (sigma_x, sigma_y) nodes, on nodes `stride`
    /// pixels apart (>= 1, on the lattice too: the pixel's box is 1 / stride nodes wide), of `kernel` at level of
    /// detail `level` (whose footprints reach as far as level_kernel_variance says).
    static PhaseTableKey pixel_averaged_key(const Kernel& kernel, int level, double sigma_x, double sigma_y,
                                            double stride = 1.0);

    /// The table for `key`, made on first use (the same for every render: images do not depend on what the cache
    /// held); an empty table where phases cannot stand for it (a window wider than PhaseFootprintTable::kMaxHalfWidth,
    /// too few phases for so narrow a footprint, the box kernel).
    CachedPhaseTable get(const PhaseTableKey& key, const Kernel& kernel);

private:
    PhaseTableCache() = default;
    struct Impl;
    std::shared_ptr<Impl> impl_;
};

/// A worker's last table: consecutive blocks mostly share one, without the cache's mutex.
struct PhaseTableMemo {
    PhaseTableKey key{{-1, -1, -1, -1}};
    CachedPhaseTable entry;

    const CachedPhaseTable& get(const PhaseTableKey& k, const Kernel& kernel) {
        if (!(k == key)) key = k, entry = PhaseTableCache::instance().get(k, kernel);
        return entry;
    }
};

}  // namespace pcvr
