/* Speed-of-light micro-benchmarks for the X-ray splat, built at bench time with
 *     cc -O3 -march=native -fopenmp sol_kernels.c -o sol_kernels -lm
 * and run by tests/bench/speed_of_light.py, which turns the numbers into bounds.
 *
 * Every test prints one JSON object per line: {"test": ..., "threads": ..., <rates>}.
 *
 * | test          | what it measures                                                            |
 * |---------------|-----------------------------------------------------------------------------|
 * | clock         | core clock: a chain of dependent integer adds (1 cycle each)                 |
 * | bw_read       | DRAM read bandwidth: sum of a 512 MiB float array                            |
 * | bw_copy       | DRAM copy bandwidth: memcpy of 256 MiB (bytes read + bytes written)          |
 * | fma_ymm/zmm   | peak FMA rate: 16 independent chains of 256/512-bit fp32 FMAs                |
 * | store_ymm     | 256-bit stores per second into an L1-resident buffer                         |
 * | rmw_ymm       | 256-bit load + add + store of doubles (the splat's accumulate) in L1         |
 * | rmw_overlap   | the same when each 4x4 block overlaps the previous one, shifted by 1 double  |
 * | gather_ymm    | 8-lane vpgatherdd from a 16 KiB table (the footprint table lookup)           |
 * | gather_zmm    | 16-lane vpgatherdd (AVX-512), same table                                     |
 * | splat_*       | a whole PCVR 4x4 splat pass over a dense n^3 volume stored as 8^3 blocks     |
 *
 * The splat_* tests repeat PCVR's first stage with nothing else: blocks of 512 float values plus an
 * active mask (OpenVDB leaf layout), an oblique orthographic projection (node coordinates affine in
 * the index), and 16 taps per voxel accumulated in double into a private node grid per thread:
 *   splat_scalar      plain C (whatever -O3 -march=native makes of it)
 *   splat_avx2        2 table gathers + 4 read-modify-write 256-bit stores per voxel, as the renderer
 *   splat_nogather    the same with constant weights: what the stores and address work cost alone
 *   splat_noscatter   the same computing weights (gathers) but summing them in registers: no stores
 *   splat_phase       weights from a per-view table of sub-node phases (4 plain loads, no gathers)
 */
#define _GNU_SOURCE
#include <immintrin.h>
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static volatile double sink_d;
static volatile uint64_t sink_u;

/* ------------------------------------------------------------------------------------------- */
static void test_clock(void) {
    const long iters = 4000000;
    double best = 1e30;
    for (int rep = 0; rep < 9; ++rep) {
        uint64_t x = 0;
        double t0 = now();
        for (long i = 0; i < iters; ++i) {
            __asm__ volatile(".rept 50\n\tadd $1, %0\n\t.endr" : "+r"(x));
        }
        double t = now() - t0;
        sink_u = x;
        if (t < best) best = t;
    }
    printf("{\"test\": \"clock\", \"threads\": 1, \"ghz\": %.4f}\n", 50.0 * iters / best * 1e-9);
}

/* ------------------------------------------------------------------------------------------- */
static void test_bandwidth(int threads) {
    const size_t n = (size_t)512 << 20 >> 2; /* 512 MiB of floats */
    float* a = aligned_alloc(64, n * sizeof(float));
    float* b = aligned_alloc(64, n * sizeof(float));
#pragma omp parallel for num_threads(threads) schedule(static)
    for (size_t i = 0; i < n; ++i) a[i] = (float)(i & 1023), b[i] = 0.0f;
    double best_read = 1e30, best_copy = 1e30;
    for (int rep = 0; rep < 5; ++rep) {
        double t0 = now();
        float total = 0;
#pragma omp parallel num_threads(threads) reduction(+ : total)
        {
            /* four independent vector sums: a strict-FP scalar sum would measure add latency */
            int id = omp_get_thread_num(), nt = omp_get_num_threads();
            size_t lo = (n / 32) * id / nt * 32, hi = (n / 32) * (id + 1) / nt * 32;
            __m256 s0 = _mm256_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
            for (size_t i = lo; i < hi; i += 32) {
                s0 = _mm256_add_ps(s0, _mm256_load_ps(a + i));
                s1 = _mm256_add_ps(s1, _mm256_load_ps(a + i + 8));
                s2 = _mm256_add_ps(s2, _mm256_load_ps(a + i + 16));
                s3 = _mm256_add_ps(s3, _mm256_load_ps(a + i + 24));
            }
            float out[8];
            _mm256_storeu_ps(out, _mm256_add_ps(_mm256_add_ps(s0, s1), _mm256_add_ps(s2, s3)));
            for (int k = 0; k < 8; ++k) total += out[k];
        }
        double t = now() - t0;
        sink_d = total;
        if (t < best_read) best_read = t;
        t0 = now();
        const size_t half = n / 2;
#pragma omp parallel num_threads(threads)
        {
            int id = omp_get_thread_num(), nt = omp_get_num_threads();
            size_t lo = half * id / nt, hi = half * (id + 1) / nt;
            memcpy(b + lo, a + lo, (hi - lo) * sizeof(float));
        }
        t = now() - t0;
        if (t < best_copy) best_copy = t;
    }
    sink_d = b[12345];
    printf("{\"test\": \"bw_read\", \"threads\": %d, \"gbps\": %.3f}\n", threads, n * 4.0 / best_read * 1e-9);
    printf("{\"test\": \"bw_copy\", \"threads\": %d, \"gbps\": %.3f}\n", threads, (n / 2) * 8.0 / best_copy * 1e-9);
    free(a);
    free(b);
}

/* ------------------------------------------------------------------------------------------- */
#define FMA_CHAINS 16
static void test_fma(int threads) {
    const long iters = 5000000;
    double best_y = 1e30, best_z = 1e30;
    for (int rep = 0; rep < 7; ++rep) {
        double t0 = now();
#pragma omp parallel num_threads(threads)
        {
            __m256 acc[FMA_CHAINS];
            const __m256 m = _mm256_set1_ps(0.999999f), c = _mm256_set1_ps(1e-7f);
            for (int k = 0; k < FMA_CHAINS; ++k) acc[k] = _mm256_set1_ps((float)k);
            for (long i = 0; i < iters; ++i) {
                for (int k = 0; k < FMA_CHAINS; ++k) acc[k] = _mm256_fmadd_ps(acc[k], m, c);
                __asm__ volatile("" : "+x"(acc[0]), "+x"(acc[1]), "+x"(acc[2]), "+x"(acc[3]), "+x"(acc[4]), "+x"(acc[5]),
                                 "+x"(acc[6]), "+x"(acc[7]));
                __asm__ volatile("" : "+x"(acc[8]), "+x"(acc[9]), "+x"(acc[10]), "+x"(acc[11]), "+x"(acc[12]),
                                 "+x"(acc[13]), "+x"(acc[14]), "+x"(acc[15]));
            }
            float s = 0, out[8];
            for (int k = 0; k < FMA_CHAINS; ++k) {
                _mm256_storeu_ps(out, acc[k]);
                s += out[0];
            }
            sink_d = s;
        }
        double t = now() - t0;
        if (t < best_y) best_y = t;
#ifdef __AVX512F__
        t0 = now();
#pragma omp parallel num_threads(threads)
        {
            __m512 acc[FMA_CHAINS];
            const __m512 m = _mm512_set1_ps(0.999999f), c = _mm512_set1_ps(1e-7f);
            for (int k = 0; k < FMA_CHAINS; ++k) acc[k] = _mm512_set1_ps((float)k);
            for (long i = 0; i < iters; ++i) {
                for (int k = 0; k < FMA_CHAINS; ++k) acc[k] = _mm512_fmadd_ps(acc[k], m, c);
                __asm__ volatile("" : "+v"(acc[0]), "+v"(acc[1]), "+v"(acc[2]), "+v"(acc[3]), "+v"(acc[4]), "+v"(acc[5]),
                                 "+v"(acc[6]), "+v"(acc[7]));
                __asm__ volatile("" : "+v"(acc[8]), "+v"(acc[9]), "+v"(acc[10]), "+v"(acc[11]), "+v"(acc[12]),
                                 "+v"(acc[13]), "+v"(acc[14]), "+v"(acc[15]));
            }
            float s = 0;
            for (int k = 0; k < FMA_CHAINS; ++k) s += _mm512_reduce_add_ps(acc[k]);
            sink_d = s;
        }
        t = now() - t0;
        if (t < best_z) best_z = t;
#endif
    }
    const double n = (double)iters * FMA_CHAINS * threads;
    printf("{\"test\": \"fma_ymm\", \"threads\": %d, \"fma_per_s\": %.4e, \"gflops\": %.2f}\n", threads, n / best_y,
           n * 16.0 / best_y * 1e-9);
#ifdef __AVX512F__
    printf("{\"test\": \"fma_zmm\", \"threads\": %d, \"fma_per_s\": %.4e, \"gflops\": %.2f}\n", threads, n / best_z,
           n * 32.0 / best_z * 1e-9);
#endif
}

/* ------------------------------------------------------------------------------------------- */
static void test_stores(int threads) {
    const long iters = 5000000;
    double best_st = 1e30, best_rmw = 1e30, best_overlap = 1e30;
    for (int rep = 0; rep < 7; ++rep) {
        double t0 = now();
#pragma omp parallel num_threads(threads)
        {
            double* buf = aligned_alloc(64, 4096 * sizeof(double));
            memset(buf, 0, 4096 * sizeof(double));
            __m256d v = _mm256_set1_pd(1.0);
            for (long i = 0; i < iters; ++i) {
                double* p = buf + ((i * 64) & 2047);
                /* 16 independent 256-bit stores to distinct lines-worth of addresses */
                _mm256_storeu_pd(p + 0, v);
                _mm256_storeu_pd(p + 4, v);
                _mm256_storeu_pd(p + 8, v);
                _mm256_storeu_pd(p + 12, v);
                _mm256_storeu_pd(p + 16, v);
                _mm256_storeu_pd(p + 20, v);
                _mm256_storeu_pd(p + 24, v);
                _mm256_storeu_pd(p + 28, v);
                _mm256_storeu_pd(p + 32, v);
                _mm256_storeu_pd(p + 36, v);
                _mm256_storeu_pd(p + 40, v);
                _mm256_storeu_pd(p + 44, v);
                _mm256_storeu_pd(p + 48, v);
                _mm256_storeu_pd(p + 52, v);
                _mm256_storeu_pd(p + 56, v);
                _mm256_storeu_pd(p + 60, v);
                __asm__ volatile("" ::: "memory");
            }
            sink_d = buf[7];
            free(buf);
        }
        double t = now() - t0;
        if (t < best_st) best_st = t;

        t0 = now();
#pragma omp parallel num_threads(threads)
        {
            /* 4 rows of a 256-column grid, 4 doubles each: the 4x4 deposit, moved one column per
             * iteration (consecutive footprints overlap, as consecutive voxels' do). */
            double* buf = aligned_alloc(64, 8 * 512 * sizeof(double));
            memset(buf, 0, 8 * 512 * sizeof(double));
            const __m256d w = _mm256_set1_pd(1e-9);
            for (long i = 0; i < iters; ++i) {
                const long col = (i * 5) & 255;
                for (int r = 0; r < 4; ++r) {
                    double* o = buf + r * 512 + col;
                    _mm256_storeu_pd(o, _mm256_add_pd(_mm256_loadu_pd(o), w));
                }
                __asm__ volatile("" ::: "memory");
            }
            sink_d = buf[100];
            free(buf);
        }
        t = now() - t0;
        if (t < best_rmw) best_rmw = t;

        t0 = now();
#pragma omp parallel num_threads(threads)
        {
            /* the same, moved by one double per iteration: each load overlaps the previous, still
             * uncommitted, misaligned store (as consecutive voxels' footprints do in PCVR) */
            double* buf = aligned_alloc(64, 8 * 512 * sizeof(double));
            memset(buf, 0, 8 * 512 * sizeof(double));
            const __m256d w = _mm256_set1_pd(1e-9);
            for (long i = 0; i < iters; ++i) {
                const long col = i & 255;
                for (int r = 0; r < 4; ++r) {
                    double* o = buf + r * 512 + col;
                    _mm256_storeu_pd(o, _mm256_add_pd(_mm256_loadu_pd(o), w));
                }
                __asm__ volatile("" ::: "memory");
            }
            sink_d = buf[100];
            free(buf);
        }
        t = now() - t0;
        if (t < best_overlap) best_overlap = t;
    }
    printf("{\"test\": \"store_ymm\", \"threads\": %d, \"stores_per_s\": %.4e}\n", threads, 16.0 * iters * threads / best_st);
    printf("{\"test\": \"rmw_ymm\", \"threads\": %d, \"stores_per_s\": %.4e}\n", threads, 4.0 * iters * threads / best_rmw);
    printf("{\"test\": \"rmw_overlap_ymm\", \"threads\": %d, \"stores_per_s\": %.4e}\n", threads,
           4.0 * iters * threads / best_overlap);
}

/* ------------------------------------------------------------------------------------------- */
#define TABLE 4096
static float table_[TABLE + 64];

static void init_table(void) {
    /* the footprint of exp(-1.4 r^2) truncated at 2, sampled in rho^2 in [0, 4): shape only matters
     * for the values, not the cost */
    for (int k = 0; k < TABLE; ++k) {
        double rho2 = (k + 0.5) * 4.0 / TABLE;
        table_[k] = (float)(exp(-1.4 * rho2) * sqrt(4.0 - rho2));
    }
    for (int k = TABLE; k < TABLE + 64; ++k) table_[k] = 0.0f;
}

static void test_gather(int threads) {
    const long iters = 2500000;
    double best = 1e30, best_z = 1e30;
    for (int rep = 0; rep < 7; ++rep) {
        double t0 = now();
#pragma omp parallel num_threads(threads)
        {
            __m256i idx[8];
            __m256 acc[8];
            for (int k = 0; k < 8; ++k) {
                idx[k] = _mm256_setr_epi32(k * 17, k * 17 + 401, k * 17 + 803, k * 17 + 1205, k * 17 + 1607, k * 17 + 2009,
                                           k * 17 + 2411, k * 17 + 2813);
                acc[k] = _mm256_setzero_ps();
            }
            const __m256i step = _mm256_set1_epi32(1), mask = _mm256_set1_epi32(TABLE - 1);
            for (long i = 0; i < iters; ++i) {
                for (int k = 0; k < 8; ++k) {
                    acc[k] = _mm256_add_ps(acc[k], _mm256_i32gather_ps(table_, idx[k], 4));
                    idx[k] = _mm256_and_si256(_mm256_add_epi32(idx[k], step), mask);
                }
            }
            float out[8], s = 0;
            for (int k = 0; k < 8; ++k) {
                _mm256_storeu_ps(out, acc[k]);
                s += out[0];
            }
            sink_d = s;
        }
        double t = now() - t0;
        if (t < best) best = t;
#ifdef __AVX512F__
        t0 = now();
#pragma omp parallel num_threads(threads)
        {
            __m512i idx[8];
            __m512 acc[8];
            for (int k = 0; k < 8; ++k) {
                idx[k] = _mm512_add_epi32(_mm512_set1_epi32(k * 17), _mm512_mullo_epi32(_mm512_set1_epi32(253),
                         _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)));
                acc[k] = _mm512_setzero_ps();
            }
            const __m512i step = _mm512_set1_epi32(1), mask = _mm512_set1_epi32(TABLE - 1);
            for (long i = 0; i < iters; ++i) {
                for (int k = 0; k < 8; ++k) {
                    acc[k] = _mm512_add_ps(acc[k], _mm512_i32gather_ps(idx[k], table_, 4));
                    idx[k] = _mm512_and_si512(_mm512_add_epi32(idx[k], step), mask);
                }
            }
            float s = 0;
            for (int k = 0; k < 8; ++k) s += _mm512_reduce_add_ps(acc[k]);
            sink_d = s;
        }
        t = now() - t0;
        if (t < best_z) best_z = t;
#endif
    }
    printf("{\"test\": \"gather_ymm\", \"threads\": %d, \"gathers_per_s\": %.4e}\n", threads, 8.0 * iters * threads / best);
#ifdef __AVX512F__
    printf("{\"test\": \"gather_zmm\", \"threads\": %d, \"gathers_per_s\": %.4e}\n", threads, 8.0 * iters * threads / best_z);
#endif
}

/* ------------------------------------------------------------------------------------------- */
/* A dense n^3 volume as 8^3 blocks (OpenVDB leaf layout: offset = x << 6 | y << 3 | z). */
typedef struct {
    int origin[3];
    uint64_t mask[8];
    float values[512];
} Block;

typedef struct {
    int n, nblocks;
    Block* blocks;
    double gx[3], gy[3], bx, by; /* node coordinates: bx + gx . ijk */
    int cols, rows;              /* node grid per thread */
} Volume;

static void make_volume(Volume* v, int n, const double* gx, const double* gy) {
    v->n = n;
    const int nb = n / 8;
    v->nblocks = nb * nb * nb;
    v->blocks = aligned_alloc(64, sizeof(Block) * (size_t)v->nblocks);
    int b = 0;
    for (int bi = 0; bi < nb; ++bi)
        for (int bj = 0; bj < nb; ++bj)
            for (int bk = 0; bk < nb; ++bk, ++b) {
                Block* blk = &v->blocks[b];
                blk->origin[0] = bi * 8, blk->origin[1] = bj * 8, blk->origin[2] = bk * 8;
                for (int w = 0; w < 8; ++w) blk->mask[w] = ~0ull;
                for (int o = 0; o < 512; ++o) blk->values[o] = 0.5f + 0.001f * (float)((o * 7 + b) & 255);
            }
    memcpy(v->gx, gx, sizeof(v->gx));
    memcpy(v->gy, gy, sizeof(v->gy));
    /* place the projected cube's bounding box at node 4 */
    double x0 = 1e30, x1 = -1e30, y0 = 1e30, y1 = -1e30;
    for (int c = 0; c < 8; ++c) {
        double p[3] = {(c & 1) ? n - 1 : 0, (c & 2) ? n - 1 : 0, (c & 4) ? n - 1 : 0};
        double x = gx[0] * p[0] + gx[1] * p[1] + gx[2] * p[2], y = gy[0] * p[0] + gy[1] * p[1] + gy[2] * p[2];
        x0 = fmin(x0, x), x1 = fmax(x1, x), y0 = fmin(y0, y), y1 = fmax(y1, y);
    }
    v->bx = 4.0 - x0;
    v->by = 4.0 - y0;
    v->cols = (int)ceil(x1 - x0) + 9;
    v->rows = (int)ceil(y1 - y0) + 9;
}

enum { SPLAT_SCALAR, SPLAT_AVX2, SPLAT_NOGATHER, SPLAT_NOSCATTER, SPLAT_PHASE, SPLAT_MODES };

/* splat_phase: an orthographic view gives every voxel the same footprint, so the 16 weights depend
 * only on the centre's sub-node phase. Tabulated for PHASES x PHASES phases (64 KiB at 32), a voxel
 * needs 4 contiguous 128-bit loads instead of 2 gathers (position rounded to 1 / (2 PHASES) node). */
#define PHASES 32
static float phase_w_[PHASES][PHASES][16] __attribute__((aligned(64)));

static void init_phase_table(void) {
    const float scale = (float)(TABLE / 4.0);
    for (int qy = 0; qy < PHASES; ++qy)
        for (int qx = 0; qx < PHASES; ++qx)
            for (int jj = 0; jj < 4; ++jj)
                for (int ii = 0; ii < 4; ++ii) {
                    const float dx = ii - (1.0f + (qx + 0.5f) / PHASES), dy = jj - (1.0f + (qy + 0.5f) / PHASES);
                    const float f = (dx * dx + dy * dy) * scale;
                    phase_w_[qy][qx][jj * 4 + ii] = table_[f < TABLE ? (int)f : TABLE];
                }
}

/* One block into one thread's grid. */
static inline uint64_t splat_block(const Volume* v, const Block* blk, double* grid, int mode, __m256* keep) {
    const double ox = v->bx + v->gx[0] * blk->origin[0] + v->gx[1] * blk->origin[1] + v->gx[2] * blk->origin[2];
    const double oy = v->by + v->gy[0] * blk->origin[0] + v->gy[1] * blk->origin[1] + v->gy[2] * blk->origin[2];
    const int cols = v->cols;
    const float scale = (float)(TABLE / 4.0), max_index = (float)TABLE;
    uint64_t count = 0;
    for (int word = 0; word < 8; ++word) {
        uint64_t bits = blk->mask[word];
        while (bits) {
            const int offset = word * 64 + __builtin_ctzll(bits);
            bits &= bits - 1;
            const float amp = blk->values[offset];
            if (amp == 0.0f) continue;
            const int i = offset >> 6, j = (offset >> 3) & 7, k = offset & 7;
            const double cx = ox + v->gx[0] * i + v->gx[1] * j + v->gx[2] * k;
            const double cy = oy + v->gy[0] * i + v->gy[1] * j + v->gy[2] * k;
            const int fc = (int)floor(cx), fr = (int)floor(cy);
            const int col = fc - 1, row = fr - 1;
            const float fx = (float)(cx - col), fy = (float)(cy - row);
            ++count;
            if (mode == SPLAT_PHASE) {
                const float* w = phase_w_[(int)((fy - 1.0f) * PHASES)][(int)((fx - 1.0f) * PHASES)];
                const __m256d a = _mm256_set1_pd((double)amp);
                for (int jj = 0; jj < 4; ++jj) {
                    double* o = grid + (size_t)(row + jj) * cols + col;
                    _mm256_storeu_pd(o, _mm256_fmadd_pd(_mm256_cvtps_pd(_mm_load_ps(w + 4 * jj)), a, _mm256_loadu_pd(o)));
                }
                continue;
            }
            if (mode == SPLAT_SCALAR) {
                for (int jj = 0; jj < 4; ++jj) {
                    double* out = grid + (size_t)(row + jj) * cols + col;
                    const float dy = (float)jj - fy;
                    for (int ii = 0; ii < 4; ++ii) {
                        const float dx = (float)ii - fx;
                        float f = (dx * dx + dy * dy) * scale;
                        out[ii] += (double)(amp * table_[f < max_index ? (int)f : TABLE]);
                    }
                }
                continue;
            }
            const __m256 dx = _mm256_sub_ps(_mm256_setr_ps(0, 1, 2, 3, 0, 1, 2, 3), _mm256_set1_ps(fx));
            const __m256 dx2 = _mm256_mul_ps(dx, dx);
            const __m256 amp8 = _mm256_set1_ps(amp);
            for (int half = 0; half < 2; ++half) {
                __m256 w;
                if (mode == SPLAT_NOGATHER) {
                    w = amp8;
                } else {
                    const __m256 dy = _mm256_sub_ps(_mm256_setr_ps(0, 0, 0, 0, 1, 1, 1, 1), _mm256_set1_ps(fy - 2.0f * half));
                    const __m256 r2 = _mm256_fmadd_ps(dy, dy, dx2);
                    const __m256i idx = _mm256_cvttps_epi32(
                        _mm256_max_ps(_mm256_min_ps(_mm256_mul_ps(r2, _mm256_set1_ps(scale)), _mm256_set1_ps(max_index)),
                                      _mm256_setzero_ps()));
                    w = _mm256_mul_ps(_mm256_i32gather_ps(table_, idx, 4), amp8);
                }
                if (mode == SPLAT_NOSCATTER) {
                    *keep = _mm256_add_ps(*keep, w);
                    continue;
                }
                double* a = grid + (size_t)(row + 2 * half) * cols + col;
                double* b = a + cols;
                _mm256_storeu_pd(a, _mm256_add_pd(_mm256_loadu_pd(a), _mm256_cvtps_pd(_mm256_castps256_ps128(w))));
                _mm256_storeu_pd(b, _mm256_add_pd(_mm256_loadu_pd(b), _mm256_cvtps_pd(_mm256_extractf128_ps(w, 1))));
            }
        }
    }
    return count;
}

static void test_splat(int n, const double* gx, const double* gy, int threads) {
    Volume v;
    make_volume(&v, n, gx, gy);
    const char* names[] = {"splat_scalar", "splat_avx2", "splat_nogather", "splat_noscatter", "splat_phase"};
    for (int mode = 0; mode < SPLAT_MODES; ++mode) {
        double best = 1e30;
        uint64_t voxels = 0;
        for (int rep = 0; rep < 3; ++rep) {
            uint64_t total = 0;
            double t0 = now();
#pragma omp parallel num_threads(threads) reduction(+ : total)
            {
                double* grid = calloc((size_t)v.cols * v.rows, sizeof(double));
                __m256 keep = _mm256_setzero_ps();
#pragma omp for schedule(dynamic, 4)
                for (int b = 0; b < v.nblocks; ++b) total += splat_block(&v, &v.blocks[b], grid, mode, &keep);
                float out[8];
                _mm256_storeu_ps(out, keep);
                sink_d = grid[(size_t)(v.rows / 2) * v.cols + v.cols / 2] + out[0];
                free(grid);
            }
            double t = now() - t0;
            voxels = total;
            if (t < best) best = t;
        }
        printf("{\"test\": \"%s\", \"threads\": %d, \"n\": %d, \"voxels_per_s\": %.4e, \"seconds\": %.5f}\n", names[mode],
               threads, n, voxels / best, best);
    }
    free(v.blocks);
}

int main(int argc, char** argv) {
    /* usage: sol_kernels [n gx0 gx1 gx2 gy0 gy1 gy2] */
    int n = 256;
    double gx[3] = {0.8660, 0.0, -0.5}, gy[3] = {-0.1710, 0.9397, -0.2962};
    if (argc >= 8) {
        n = atoi(argv[1]);
        for (int k = 0; k < 3; ++k) gx[k] = atof(argv[2 + k]), gy[k] = atof(argv[5 + k]);
    }
    const int cores = omp_get_num_procs();
    init_table();
    init_phase_table();
    setvbuf(stdout, NULL, _IOLBF, 0);
    test_clock();
    const int counts[2] = {1, cores};
    for (int c = 0; c < (cores > 1 ? 2 : 1); ++c) {
        const int t = counts[c];
        test_bandwidth(t);
        test_fma(t);
        test_stores(t);
        test_gather(t);
        test_splat(n, gx, gy, t);
    }
    return 0;
}
