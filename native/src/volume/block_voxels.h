/// @file block_voxels.h
/// @brief Walking the voxels of a VoxelBlock: which ones a splat visits, and where they are.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "pcvr/grid.h"
#include "pcvr/math.h"

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define PCVR_AVX2 1
#endif

namespace pcvr {

/// Calls fn(offset, value) for the active, finite, non-zero voxels of a block. Non-finite values
/// are skipped so that one bad voxel cannot poison the pixels of everything else in the image.
template <class Fn>
inline void for_each_voxel(const VoxelBlock& block, Fn&& fn) {
    for (int word = 0; word < 8; ++word) {
        uint64_t bits = block.mask[word];
        while (bits) {
            const int offset = word * 64 + __builtin_ctzll(bits);
            bits &= bits - 1;
            const float v = block.value(offset);
            if (v != 0.0f && std::isfinite(v)) fn(offset, v);
        }
    }
}

/// Index coordinates of a voxel given by its offset in the block (k fastest).
inline Vec3 voxel_position(const VoxelBlock& block, int offset) {
    return {double(block.origin[0] + (offset >> 6)), double(block.origin[1] + ((offset >> 3) & 7)),
            double(block.origin[2] + (offset & 7))};
}

/// Number of active voxels in the block.
inline int active_count(const VoxelBlock& block) {
    int n = 0;
    for (uint64_t w : block.mask) n += __builtin_popcountll(w);
    return n;
}

/// Every voxel of the block is active (most blocks of a CT scan or a dense simulation).
inline bool all_active(const VoxelBlock& block) {
    return std::all_of(block.mask.begin(), block.mask.end(), [](uint64_t w) { return w == ~uint64_t(0); });
}

#ifdef PCVR_AVX2
/// All-ones in the lanes whose value is finite and non-zero: the voxels a splat adds.
inline __m256 finite_non_zero(__m256 v) {
    const __m256 magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0f), v);
    return _mm256_and_ps(_mm256_cmp_ps(magnitude, _mm256_set1_ps(INFINITY), _CMP_LT_OQ),
                         _mm256_cmp_ps(magnitude, _mm256_setzero_ps(), _CMP_GT_OQ));
}

/// Calls fn(i, j, k, v) for the voxels of a block eight at a time: their index offsets within the
/// block and their values, as eight float lanes. Lanes that hold no voxel have value 0, which
/// every splat skips (as it skips zero and non-finite values). `full`: every voxel is to be
/// splatted, so the block goes column by column along k without reading its mask; otherwise the
/// active, finite, non-zero voxels for which keep(offset) holds are gathered.
template <class Keep, class Fn>
inline void for_each_batch(const VoxelBlock& block, bool full, Keep&& keep, Fn&& fn) {
    if (full) {
        const __m256 k = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
        for (int i = 0; i < 8; ++i)
            for (int j = 0; j < 8; ++j) {
                const __m256 v = block.values ? _mm256_loadu_ps(block.values + (i * 8 + j) * 8) : _mm256_set1_ps(block.constant);
                fn(_mm256_set1_ps(float(i)), _mm256_set1_ps(float(j)), k, v);
            }
        return;
    }
    alignas(32) int32_t offsets[8];
    alignas(32) float values[8];
    int n = 0;
    auto flush = [&] {
        std::fill(offsets + n, offsets + 8, 0);
        std::fill(values + n, values + 8, 0.0f);
        const __m256i offset = _mm256_load_si256(reinterpret_cast<const __m256i*>(offsets));
        const __m256i seven = _mm256_set1_epi32(7);
        fn(_mm256_cvtepi32_ps(_mm256_srli_epi32(offset, 6)),
           _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(offset, 3), seven)),
           _mm256_cvtepi32_ps(_mm256_and_si256(offset, seven)), _mm256_load_ps(values));
        n = 0;
    };
    for_each_voxel(block, [&](int offset, float v) {
        if (!keep(offset)) return;
        offsets[n] = offset;
        values[n] = v;
        if (++n == 8) flush();
    });
    if (n) flush();
}
#endif

}  // namespace pcvr
