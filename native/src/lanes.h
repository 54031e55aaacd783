/// @file lanes.h
/// @brief Eight float lanes (and four double lanes) as GCC vector types, for loops that read like scalar code.
///
/// With AVX2 each operation is one instruction; the portable build (no AVX2) gets the same code in SSE
/// halves, so both builds share one implementation. Only the table gather needs an intrinsic.
#pragma once

#include <cmath>
#include <cstdint>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

namespace pcvr {

typedef float float8 __attribute__((vector_size(32)));
typedef int32_t int8x __attribute__((vector_size(32)));  // what comparisons of float8 give
typedef double double4 __attribute__((vector_size(32)));
typedef long long long4 __attribute__((vector_size(32)));

inline float8 broadcast8(float x) { return float8{} + x; }
inline float8 lane_index8() { return float8{0, 1, 2, 3, 4, 5, 6, 7}; }
inline float8 min8(float8 a, float8 b) { return a < b ? a : b; }
inline float8 max8(float8 a, float8 b) { return a > b ? a : b; }
inline float8 clamp8(float8 x, float lo, float hi) { return min8(max8(x, broadcast8(lo)), broadcast8(hi)); }
inline float8 abs8(float8 x) { return x < 0 ? -x : x; }
inline float8 select8(int8x mask, float8 a, float8 b) { return mask ? a : b; }
inline bool any8(int8x mask) {
    for (int l = 0; l < 8; ++l)
        if (mask[l]) return true;
    return false;
}

/// table[index] per lane; indices must be valid.
inline float8 gather8(const float* table, int8x index) {
#if defined(__AVX2__) && defined(__FMA__)
    return float8(_mm256_i32gather_ps(table, __m256i(index), 4));
#else
    float8 out;
    for (int l = 0; l < 8; ++l) out[l] = table[index[l]];
    return out;
#endif
}

inline double4 sqrt4(double4 x) {
    for (int l = 0; l < 4; ++l) x[l] = std::sqrt(x[l]);
    return x;
}

}  // namespace pcvr
