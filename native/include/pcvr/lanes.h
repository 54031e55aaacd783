/// @file lanes.h
/// @brief Eight float lanes (and four double lanes) as GCC vector types, for loops that read like scalar code.
///
/// With AVX2 each operation is one instruction; the portable build (no AVX2) gets the same code in SSE
/// halves, so both builds share one implementation. Only table lookups need intrinsics.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>

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
/// Bit l set where lane l of the mask is.
inline uint32_t lane_mask(int8x mask) {
#if defined(__AVX2__) && defined(__FMA__)
    return uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(__m256i(mask))));
#else
    uint32_t bits = 0;
    for (int l = 0; l < 8; ++l) bits |= uint32_t(mask[l] != 0) << l;
    return bits;
#endif
}
inline bool any8(int8x mask) { return lane_mask(mask) != 0; }

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

/// Whether bit index of `bits` is set, per lane (all ones or zero); index >> 5 must be a valid word.
inline int8x bit_set8(const uint32_t* bits, int8x index) {
    const int8x word = index >> 5;
#if defined(__AVX2__) && defined(__FMA__)
    const int8x words = int8x(_mm256_i32gather_epi32(reinterpret_cast<const int*>(bits), __m256i(word), 4));
#else
    int8x words;
    for (int l = 0; l < 8; ++l) words[l] = int32_t(bits[word[l]]);
#endif
    // Logical shifts: the bit's word may have its top bit set.
    typedef uint32_t uint8x __attribute__((vector_size(32)));
    return -int8x((uint8x(words) >> uint8x(index & 31)) & 1u);
}

/// table[i] + f (table[i + 1] - table[i]) per lane (i + 1 valid too): each lane's two entries in one
/// 64-bit load, where a pair of gathers took several times as long on the AMD cores we measure on.
inline float8 lerp_pairs8(const float* table, int8x i, float8 f) {
#if defined(__AVX2__) && defined(__FMA__)
    // 64 bits at any float's address (vmovq): not a double's load, which would have to be aligned.
    auto pair = [&](int l) { return _mm_castsi128_pd(_mm_loadl_epi64(reinterpret_cast<const __m128i_u*>(table + i[l]))); };
    // Lanes a and b's pairs side by side: [t a, t a + 1, t b, t b + 1].
    auto pairs = [&](int a, int b) { return _mm_castpd_ps(_mm_unpacklo_pd(pair(a), pair(b))); };
    const __m128 p01 = pairs(0, 1), p23 = pairs(2, 3), p45 = pairs(4, 5), p67 = pairs(6, 7);
    const __m256 first = _mm256_set_m128(p45, p01), second = _mm256_set_m128(p67, p23);
    const float8 lo = float8(_mm256_shuffle_ps(first, second, 0x88)), hi = float8(_mm256_shuffle_ps(first, second, 0xDD));
#else
    float8 lo, hi;
    for (int l = 0; l < 8; ++l) lo[l] = table[i[l]], hi[l] = table[i[l] + 1];
#endif
    return lo + f * (hi - lo);
}

/// For a table of four floats per entry: entries i and i + 1 per lane interpolated f of the way, as
/// four vectors (each entry's first float in out[0], ...): one 256-bit load per lane and a transpose.
inline void lerp_quads8(const float* table, int8x i, float8 f, float8 (&out)[4]) {
#if defined(__AVX2__) && defined(__FMA__)
    auto entry = [&](int l) {
        const __m256 pair = _mm256_loadu_ps(table + 4 * size_t(i[l]));
        const __m128 a = _mm256_castps256_ps128(pair), b = _mm256_extractf128_ps(pair, 1);
        return _mm_fmadd_ps(_mm_set1_ps(f[l]), _mm_sub_ps(b, a), a);
    };
    __m256 rows[4];  // lanes l and l + 4
    for (int l = 0; l < 4; ++l) rows[l] = _mm256_set_m128(entry(l + 4), entry(l));
    const __m256 xy01 = _mm256_unpacklo_ps(rows[0], rows[1]), zw01 = _mm256_unpackhi_ps(rows[0], rows[1]);
    const __m256 xy23 = _mm256_unpacklo_ps(rows[2], rows[3]), zw23 = _mm256_unpackhi_ps(rows[2], rows[3]);
    out[0] = float8(_mm256_shuffle_ps(xy01, xy23, 0x44));
    out[1] = float8(_mm256_shuffle_ps(xy01, xy23, 0xEE));
    out[2] = float8(_mm256_shuffle_ps(zw01, zw23, 0x44));
    out[3] = float8(_mm256_shuffle_ps(zw01, zw23, 0xEE));
#else
    for (int c = 0; c < 4; ++c)
        for (int l = 0; l < 8; ++l) {
            const float a = table[4 * size_t(i[l]) + c], b = table[4 * size_t(i[l] + 1) + c];
            out[c][l] = a + f[l] * (b - a);
        }
#endif
}

inline double4 sqrt4(double4 x) {
    for (int l = 0; l < 4; ++l) x[l] = std::sqrt(x[l]);
    return x;
}

inline float8 load8(const float* p) {
    float8 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store8(float* p, float8 v) { std::memcpy(p, &v, sizeof v); }

inline float8 sqrt8(float8 x) {
#if defined(__AVX2__) && defined(__FMA__)
    return float8(_mm256_sqrt_ps(__m256(x)));
#else
    for (int l = 0; l < 8; ++l) x[l] = std::sqrt(x[l]);
    return x;
#endif
}

/// 1 / sqrt(x) to about 2 ulp: the approximation and one Newton step, shorter than a square root and a
/// division where a loop waits on it. x must be positive and normal.
inline float8 rsqrt8(float8 x) {
#if defined(__AVX2__) && defined(__FMA__)
    const float8 r = float8(_mm256_rsqrt_ps(__m256(x)));
    return r * (1.5f - (0.5f * x) * (r * r));
#else
    return 1.0f / sqrt8(x);
#endif
}

/// e^x to about 2 ulp for x in [-87, 88] (outside: clamped), by the usual split x = n ln 2 + r,
/// a degree-6 polynomial for e^r on |r| <= ln 2 / 2 and n put into the exponent bits.
inline float8 exp8(float8 x) {
    x = clamp8(x, -87.0f, 88.0f);
    const float8 t = x * 1.44269504f;  // x / ln 2, rounded to the nearest integer n
    const float8 n = __builtin_convertvector(__builtin_convertvector(t + select8(t < 0, broadcast8(-0.5f), broadcast8(0.5f)), int8x), float8);
    const float8 r = x - n * 0.693359375f - n * -2.12194440e-4f;  // ln 2 in two parts
    float8 p = broadcast8(1.9875691500e-4f);
    p = p * r + 1.3981999507e-3f;
    p = p * r + 8.3334519073e-3f;
    p = p * r + 4.1665795894e-2f;
    p = p * r + 1.6666665459e-1f;
    p = p * r + 5.0000001201e-1f;
    p = p * r * r + r + 1.0f;
    const int8x bits = (__builtin_convertvector(n, int8x) + 127) << 23;
    float8 scale;
    std::memcpy(&scale, &bits, sizeof scale);
    return p * scale;
}

/// ln x to about 2 ulp for finite x > 0 (Cephes' logf): x = m 2^e with m in [sqrt(1/2), sqrt(2)), a
/// degree-9 polynomial in m - 1 and e ln 2 added in two parts.
inline float8 log8(float8 x) {
    int8x bits;
    std::memcpy(&bits, &x, sizeof bits);
    int8x e = ((bits >> 23) & 0xff) - 126;
    bits = (bits & int32_t(0x807fffff)) | 0x3f000000;  // the mantissa in [1/2, 1)
    float8 m;
    std::memcpy(&m, &bits, sizeof m);
    const int8x small = m < 0.707106781f;
    e += small;  // -1 where true
    m = select8(small, m + m, m) - 1.0f;
    const float8 z = m * m;
    float8 p = broadcast8(7.0376836292e-2f);
    p = p * m - 1.1514610310e-1f;
    p = p * m + 1.1676998740e-1f;
    p = p * m - 1.2420140846e-1f;
    p = p * m + 1.4249322787e-1f;
    p = p * m - 1.6668057665e-1f;
    p = p * m + 2.0000714765e-1f;
    p = p * m - 2.4999993993e-1f;
    p = p * m + 3.3333331174e-1f;
    const float8 n = __builtin_convertvector(e, float8);
    return m + (p * m * z + n * -2.12194440e-4f - 0.5f * z) + n * 0.693359375f;
}

/// ln(1 + x) for x > -1, accurate for small |x| too: ln u scaled by x / (u - 1), which undoes the
/// rounding of u = 1 + x (Goldberg's trick).
inline float8 log1p8(float8 x) {
    const float8 u = 1.0f + x;
    const int8x exact = u == 1.0f;
    return select8(exact, x, log8(u) * (x / select8(exact, broadcast8(1.0f), u - 1.0f)));
}

/// Three vectors of eight lanes: eight 3-D points or directions.
struct Vec3x8 {
    float8 x, y, z;
};
inline Vec3x8 operator+(const Vec3x8& a, const Vec3x8& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3x8 operator-(const Vec3x8& a, const Vec3x8& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3x8 operator*(const Vec3x8& a, float8 s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3x8 operator*(const Vec3x8& a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline float8 dot(const Vec3x8& a, const Vec3x8& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3x8 cross(const Vec3x8& a, const Vec3x8& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

}  // namespace pcvr
