/// @file block_tile.h
/// @brief Block-sized float tiles that small splat windows are added into before the grid.
///
/// Consecutive voxels of a block land less than a node apart, so each one's rows overlap the
/// previous one's at a shifted address, and a load cannot take its data from such a store before
/// the store is written: every voxel's updates would wait on the voxel before. Small windows
/// (PCVR's, bilinear spreading's) are therefore added into a tile around the block first, with
/// consecutive voxels taking turns over kTileCopies copies, so an update waits only on the voxel
/// four places back, and the tile stays in L1. Float is enough in a tile (a node gets at most a few
/// dozen contributions from one block); the copies are added into the double grid once per block.
#pragma once

#include <algorithm>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "splat/splat_grid.h"

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace pcvr {

constexpr int kTileCopies = 4;
constexpr int kTileFloats = 64 * 64;  ///< per copy: blocks whose windows span more go to the grid directly
/// Adding a tile into the grid costs about as much as splatting a few hundred voxels through it
/// saves: sparser blocks go to the grid directly.
constexpr int kTileMinVoxels = 256;

/// Where a block's deposits go: a tile at grid node (col0, row0), or the grid itself.
struct DepositRegion {
    int col0 = 0, row0 = 0;  ///< grid node of the region's (0, 0)
    int width = 0, height = 0;
    int pitch = 0;           ///< floats per tile row (>= width: rows may be written in whole vectors)
    bool tiled = false;

    static DepositRegion whole(const SplatGrid& grid) { return {0, 0, grid.columns(), grid.rows(), grid.columns(), false}; }
    /// A tile of width x height nodes at (col0, row0) with `slack` floats after each row, or the
    /// whole grid when that does not fit a tile.
    static DepositRegion tile_or_grid(int col0, int row0, int width, int height, int slack, const SplatGrid& grid) {
        const int pitch = width + slack;
        if (width <= 0 || height <= 0 || pitch * height > kTileFloats) return whole(grid);
        return {col0, row0, width, height, pitch, true};
    }
};

/// A worker's scratch memory for the batched splats, reused from block to block.
struct SplatScratch {
    std::vector<float> tiles;  ///< kTileCopies tiles, zero between blocks
    uint64_t taps = 0;         ///< window taps the splats wrote (the render's work, for its statistics)

    float* tile_copies() {
        if (tiles.empty()) tiles.assign(size_t(kTileCopies) * kTileFloats, 0.0f);
        return tiles.data();
    }
};

/// The tile copy that the voxel taking turn `turn` adds into.
inline float* tile_copy(float* tiles, int turn) { return tiles + size_t(turn % kTileCopies) * kTileFloats; }

/// Adds the tile copies into the grid (clipped to it) and leaves them zero for the next block.
inline void flush_tile(const DepositRegion& r, float* tiles, SplatGrid& grid) {
    const int c0 = std::max(0, -r.col0), c1 = std::min(r.width, grid.columns() - r.col0);
    const int j0 = std::max(0, -r.row0), j1 = std::min(r.height, grid.rows() - r.row0);
    const float* t[kTileCopies];
    for (int k = 0; k < kTileCopies; ++k) t[k] = tile_copy(tiles, k);
    for (int j = j0; j < j1; ++j) {
        const size_t row = size_t(j) * r.pitch;
        double* out = grid.row(r.row0 + j) + r.col0;
        for (int c = c0; c < c1; ++c) out[c] += double((t[0][row + c] + t[1][row + c]) + (t[2][row + c] + t[3][row + c]));
    }
    for (int k = 0; k < kTileCopies; ++k) std::fill_n(tile_copy(tiles, k), size_t(r.pitch) * r.height, 0.0f);
}

#if defined(__AVX2__) && defined(__FMA__)
/// out[0..3] += w, into a tile (float) or the grid (double).
template <class T>
inline void accumulate4(T* out, __m128 w) {
    if constexpr (std::is_same_v<T, float>)
        _mm_storeu_ps(out, _mm_add_ps(_mm_loadu_ps(out), w));
    else
        _mm256_storeu_pd(out, _mm256_add_pd(_mm256_loadu_pd(out), _mm256_cvtps_pd(w)));
}

/// out[0..7] += w, into a tile (float) or the grid (double).
template <class T>
inline void accumulate8(T* out, __m256 w) {
    if constexpr (std::is_same_v<T, float>) {
        _mm256_storeu_ps(out, _mm256_add_ps(_mm256_loadu_ps(out), w));
    } else {
        accumulate4(out, _mm256_castps256_ps128(w));
        accumulate4(out + 4, _mm256_extractf128_ps(w, 1));
    }
}
#endif

/// Flushes a block's tile when the block is done, whichever way its splat returns.
class TileFlush {
public:
    TileFlush(const DepositRegion& region, float* tiles, SplatGrid& grid) : region_(region), tiles_(tiles), grid_(grid) {}
    ~TileFlush() {
        if (region_.tiled) flush_tile(region_, tiles_, grid_);
    }
    TileFlush(const TileFlush&) = delete;
    TileFlush& operator=(const TileFlush&) = delete;

private:
    const DepositRegion& region_;
    float* tiles_;
    SplatGrid& grid_;
};

}  // namespace pcvr
