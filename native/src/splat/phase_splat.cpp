#include "splat/phase_splat.h"

#include <algorithm>
#include <array>
#include <optional>
#include <cmath>
#include <utility>

#include "splat/block_tile.h"
#include "volume/block_voxels.h"

namespace pcvr {

namespace {

/// A window tap by tap, clipped to the grid: for windows that stick out of it (the same table as
/// the vector path keeps the image shift-invariant up to the grid's edges), and the whole splat of
/// builds without AVX2. (col, row): the window's top-left tap; (fx, fy): the centre's phase.
void deposit_clipped(SplatGrid& g, int col, int row, float fx, float fy, float amp, const PhaseFootprintTable& table) {
    const PhaseFootprintTable::Blend b = table.blend(fx, fy);
    const int window = table.window(), row_floats = table.pitch();
    const int j0 = std::max(0, -row), j1 = std::min(window, g.rows() - row);
    const int i0 = std::max(0, -col), i1 = std::min(window, g.columns() - col);
    for (int j = j0; j < j1; ++j) {
        double* out = g.row(row + j) + col;
        for (int i = i0; i < i1; ++i) {
            const size_t t = size_t(j) * row_floats + i;
            out[i] += double(amp) * (b.coeff[0] * b.entry[0][t] + b.coeff[1] * b.entry[1][t] +
                                     b.coeff[2] * b.entry[2][t] + b.coeff[3] * b.entry[3][t]);
        }
    }
}

#ifdef PCVR_AVX2

/// The windows the deposits are specialised for.
enum class WindowKind {
    Tent2x2,   ///< bilinear spreading: the blend coefficients are the four weights
    Table4x4,  ///< PCVR: two rows of four taps per vector, sizes known at compile time
    Table,     ///< any other window (regular splatting): rows of whole vectors
};

/// A table's window sizes; compile-time constants for the fixed windows.
struct WindowLayout {
    int half_width, window, pitch, phases, entry_size;
};

template <WindowKind Kind>
inline WindowLayout window_layout(const PhaseFootprintTable& t) {
    if constexpr (Kind == WindowKind::Tent2x2)
        return {1, 2, 8, 1, 16};
    else if constexpr (Kind == WindowKind::Table4x4)
        return {2, 4, 4, PhaseFootprintTable::kPhases4x4, 16};
    else
        return {t.half_width(), t.window(), t.pitch(), t.phases(), int(t.entry_size())};
}

/// One block's part of the mapping as eight-lane constants. Positions are floats relative to the
/// node holding the block's origin: within a block they stay below a few dozen nodes, where a
/// float resolves about 1e-6 node, and the image stays exactly shift-invariant by whole nodes.
struct BlockFrame {
    __m256 ox, oy;  // the origin's position inside its node, in [0, 1)
    __m256 gxi, gxj, gxk, gyi, gyj, gyk;
    __m256 amp_per_value;
    __m256i corner_x, corner_y;  // window corner of a voxel at the origin's node, in the region
    __m256i last_x, last_y;      // the largest corner whose window fits the region
    DepositRegion region;        // the block's tile, or the whole grid
};

/// The frame's deposit region and window corners, for voxels whose positions, relative to storage node
/// (origin_x, origin_y), fall in nodes [x0, x1] x [y0, y1] (`nodes`; none: unknown): a tile around their windows,
/// which reach window - 1 nodes beyond their corner, where they fit one, else the grid.
void place_region(BlockFrame& f, int origin_x, int origin_y, const std::optional<std::array<int, 4>>& nodes, WindowLayout w,
                  const SplatGrid& grid, int slack = 0) {
    int shift_x = -origin_x, shift_y = -origin_y;
    f.region = DepositRegion::whole(grid);
    if (nodes) {
        const auto [x0, x1, y0, y1] = *nodes;
        const int tx = x0 - w.half_width + 1, ty = y0 - w.half_width + 1;
        f.region = DepositRegion::tile_or_grid(origin_x + tx, origin_y + ty, x1 - x0 + w.window, y1 - y0 + w.window, slack, grid);
        if (f.region.tiled) shift_x = tx, shift_y = ty;
    }
    f.corner_x = _mm256_set1_epi32(1 - w.half_width - shift_x);
    f.corner_y = _mm256_set1_epi32(1 - w.half_width - shift_y);
    f.last_x = _mm256_set1_epi32(f.region.width - w.window);
    f.last_y = _mm256_set1_epi32(f.region.height - w.window);
}

/// The frame of `block`, with a tile around its windows when `Tiled` and they fit one.
template <bool Tiled>
BlockFrame block_frame(const VoxelBlock& block, const OrthographicMapping& map, WindowLayout w, const SplatGrid& grid) {
    const Vec3 origin{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])};
    const double x = map.node_x(origin), y = map.node_y(origin);
    const double node_x = std::floor(x), node_y = std::floor(y);
    BlockFrame f;
    f.ox = _mm256_set1_ps(float(x - node_x));
    f.oy = _mm256_set1_ps(float(y - node_y));
    f.gxi = _mm256_set1_ps(float(map.gx.x));
    f.gxj = _mm256_set1_ps(float(map.gx.y));
    f.gxk = _mm256_set1_ps(float(map.gx.z));
    f.gyi = _mm256_set1_ps(float(map.gy.x));
    f.gyj = _mm256_set1_ps(float(map.gy.y));
    f.gyk = _mm256_set1_ps(float(map.gy.z));
    f.amp_per_value = _mm256_set1_ps(map.amp_per_value);

    std::optional<std::array<int, 4>> nodes;
    if (Tiled && active_count(block) >= kTileMinVoxels) {
        // The nodes the block's voxels fall in, from its corners, one node wider on each side for
        // the rounding of float positions; windows reach window - 1 nodes beyond their corner.
        const int span = VoxelBlock::kDim - 1;
        auto node_range = [&](double frac, const Vec3& g) {
            const double lo = frac + span * (std::min(g.x, 0.0) + std::min(g.y, 0.0) + std::min(g.z, 0.0));
            const double hi = frac + span * (std::max(g.x, 0.0) + std::max(g.y, 0.0) + std::max(g.z, 0.0));
            return std::pair<int, int>{int(std::floor(lo)) - 1, int(std::floor(hi)) + 1};
        };
        const auto [x0, x1] = node_range(x - node_x, map.gx);
        const auto [y0, y1] = node_range(y - node_y, map.gy);
        nodes = std::array<int, 4>{x0, x1, y0, y1};
    }
    place_region(f, int(node_x), int(node_y), nodes, w, grid);
    return f;
}

/// Eight voxels ready to deposit.
struct VoxelBatch {
    alignas(32) int32_t col[8], row[8];  // window corner in the region
    alignas(32) int32_t entry[8];        // offset of the phase's window in the table, floats
    alignas(32) float coeff[4][8];       // bilinear blend of the four phases around the centre, times amplitude
    alignas(32) float fx[8], fy[8], amp[8];  // for windows the grid's edge clips
    uint32_t live;    // lanes holding a finite, non-zero voxel
    uint32_t inside;  // lanes whose window lies inside the region
};

/// The vector pass: node positions (lx, ly) relative to the frame and values v of eight voxels.
inline void prepare(__m256 lx, __m256 ly, __m256 v, const BlockFrame& f, WindowLayout w, VoxelBatch& b) {
    const __m256 node_x = _mm256_floor_ps(lx), node_y = _mm256_floor_ps(ly);
    const __m256i col = _mm256_add_epi32(_mm256_cvttps_epi32(node_x), f.corner_x);
    const __m256i row = _mm256_add_epi32(_mm256_cvttps_epi32(node_y), f.corner_y);
    const __m256 fx = _mm256_sub_ps(lx, node_x), fy = _mm256_sub_ps(ly, node_y);
    const __m256i outside = _mm256_or_si256(
        _mm256_or_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), col), _mm256_cmpgt_epi32(_mm256_setzero_si256(), row)),
        _mm256_or_si256(_mm256_cmpgt_epi32(col, f.last_x), _mm256_cmpgt_epi32(row, f.last_y)));

    // The same phase arithmetic as PhaseFootprintTable::blend, eight lanes at once.
    const __m256 phases = _mm256_set1_ps(float(w.phases));
    const __m256i last_phase = _mm256_set1_epi32(w.phases - 1);
    const __m256 sx = _mm256_mul_ps(fx, phases), sy = _mm256_mul_ps(fy, phases);
    const __m256i px = _mm256_min_epi32(_mm256_cvttps_epi32(sx), last_phase);
    const __m256i py = _mm256_min_epi32(_mm256_cvttps_epi32(sy), last_phase);
    const __m256 ax = _mm256_sub_ps(sx, _mm256_cvtepi32_ps(px)), ay = _mm256_sub_ps(sy, _mm256_cvtepi32_ps(py));
    const __m256i entry = _mm256_mullo_epi32(
        _mm256_add_epi32(_mm256_mullo_epi32(py, _mm256_set1_epi32(w.phases + 1)), px), _mm256_set1_epi32(w.entry_size));

    const __m256 amp = _mm256_mul_ps(v, f.amp_per_value);
    const __m256 one = _mm256_set1_ps(1.0f);
    const __m256 left = _mm256_sub_ps(one, ax);
    const __m256 top = _mm256_mul_ps(_mm256_sub_ps(one, ay), amp), bottom = _mm256_mul_ps(ay, amp);

    _mm256_store_si256(reinterpret_cast<__m256i*>(b.col), col);
    _mm256_store_si256(reinterpret_cast<__m256i*>(b.row), row);
    _mm256_store_si256(reinterpret_cast<__m256i*>(b.entry), entry);
    _mm256_store_ps(b.coeff[0], _mm256_mul_ps(left, top));
    _mm256_store_ps(b.coeff[1], _mm256_mul_ps(ax, top));
    _mm256_store_ps(b.coeff[2], _mm256_mul_ps(left, bottom));
    _mm256_store_ps(b.coeff[3], _mm256_mul_ps(ax, bottom));
    _mm256_store_ps(b.fx, fx);
    _mm256_store_ps(b.fy, fy);
    _mm256_store_ps(b.amp, amp);
    b.live = uint32_t(_mm256_movemask_ps(finite_non_zero(v)));
    b.inside = ~uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(outside))) & 0xffu;
}

/// Lane l's window interpolated between its four phases (table entries from e0), added row by row
/// into doubles (the grid) or floats (a tile) with a row pitch of `pitch`. Rows are whole vectors;
/// lanes past the window hold zero weights, and the grid's padding takes the stores past its last
/// column.
template <WindowKind Kind, class T>
inline void add_window(T* out, size_t pitch, const float* e0, const VoxelBatch& b, int l, WindowLayout w) {
    const float* e1 = e0 + w.entry_size;
    const float* e2 = e0 + size_t(w.phases + 1) * w.entry_size;
    const float* e3 = e2 + w.entry_size;
    const __m256 c0 = _mm256_broadcast_ss(&b.coeff[0][l]), c1 = _mm256_broadcast_ss(&b.coeff[1][l]);
    const __m256 c2 = _mm256_broadcast_ss(&b.coeff[2][l]), c3 = _mm256_broadcast_ss(&b.coeff[3][l]);
    auto weights = [&](size_t t) {
        return _mm256_fmadd_ps(c3, _mm256_loadu_ps(e3 + t),
               _mm256_fmadd_ps(c2, _mm256_loadu_ps(e2 + t),
               _mm256_fmadd_ps(c1, _mm256_loadu_ps(e1 + t), _mm256_mul_ps(c0, _mm256_loadu_ps(e0 + t)))));
    };
    if constexpr (Kind == WindowKind::Table4x4) {
        for (int half = 0; half < 2; ++half, out += 2 * pitch) {  // two rows of four taps per vector
            const __m256 wv = weights(8 * half);
            accumulate4(out, _mm256_castps256_ps128(wv));
            accumulate4(out + pitch, _mm256_extractf128_ps(wv, 1));
        }
    } else {
        for (int j = 0; j < w.window; ++j, out += pitch)
            for (int i = 0; i < w.pitch; i += 8) accumulate8(out + i, weights(size_t(j) * w.pitch + i));
    }
}

/// Lane l's window added at `out` (row pitch `pitch`).
template <WindowKind Kind, class T>
inline void add_lane(T* out, size_t pitch, const float* entries, const VoxelBatch& b, int l, WindowLayout w) {
    if constexpr (Kind == WindowKind::Tent2x2) {
        // The tent's phase windows are unit impulses, so the blend coefficients are the weights.
        out[0] += b.coeff[0][l];
        out[1] += b.coeff[1][l];
        out[pitch] += b.coeff[2][l];
        out[pitch + 1] += b.coeff[3][l];
    } else {
        add_window<Kind>(out, pitch, entries + b.entry[l], b, l, w);
    }
}

/// The second pass: every live voxel's window added to the block's tile (lanes taking turns over
/// its copies) or straight to the grid.
template <WindowKind Kind>
inline void deposit(const VoxelBatch& b, const PhaseFootprintTable& table, WindowLayout w, const BlockFrame& f,
                    float* tiles, SplatGrid& grid) {
    // Locals, so that the compiler need not reload them after every store.
    const float* const entries = table.data();
    const uint32_t inside = b.live & b.inside;
    if (f.region.tiled) {
        const size_t pitch = size_t(f.region.pitch);
        for (uint32_t todo = inside; todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            add_lane<Kind>(tile_copy(tiles, l) + size_t(b.row[l]) * pitch + b.col[l], pitch, entries, b, l, w);
        }
    } else {
        double* const base = grid.row(0);
        const size_t columns = size_t(grid.columns());
        for (uint32_t todo = inside; todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            add_lane<Kind>(base + size_t(b.row[l]) * columns + b.col[l], columns, entries, b, l, w);
        }
    }
    for (uint32_t clipped = b.live & ~b.inside; clipped; clipped &= clipped - 1) {
        const int l = __builtin_ctz(clipped);
        deposit_clipped(grid, f.region.col0 + b.col[l], f.region.row0 + b.row[l], b.fx[l], b.fy[l], b.amp[l], table);
    }
}

template <WindowKind Kind>
uint64_t splat_block(const VoxelBlock& block, const OrthographicMapping& map, const PhaseFootprintTable& table,
                     const ViewProjection* clip_view, SplatGrid& grid, SplatScratch& scratch) {
    const WindowLayout w = window_layout<Kind>(table);
    const BlockFrame f = block_frame<Kind != WindowKind::Table>(block, map, w, grid);
    float* tiles = f.region.tiled ? scratch.tile_copies() : nullptr;
    const TileFlush flush(f.region, tiles, grid);
    VoxelBatch b;
    uint64_t count = 0;
    auto keep = [&](int offset) {
        return !clip_view || ViewProjection::inside_clip_range(clip_view->to_clip(voxel_position(block, offset)));
    };
    for_each_batch(block, !clip_view && all_active(block), keep, [&](__m256 i, __m256 j, __m256 k, __m256 v) {
        prepare(_mm256_fmadd_ps(f.gxk, k, _mm256_fmadd_ps(f.gxj, j, _mm256_fmadd_ps(f.gxi, i, f.ox))),
                _mm256_fmadd_ps(f.gyk, k, _mm256_fmadd_ps(f.gyj, j, _mm256_fmadd_ps(f.gyi, i, f.oy))), v, f, w, b);
        count += __builtin_popcount(b.live);
        deposit<Kind>(b, table, w, f, tiles, grid);
    });
    return count;
}

/// Eight voxels' values of a block's affine model (block_linearisation.h).
inline __m256 evaluate(const AffineInBlock& f, __m256 i, __m256 j, __m256 k) {
    return _mm256_fmadd_ps(_mm256_set1_ps(f.dk), k,
                           _mm256_fmadd_ps(_mm256_set1_ps(f.dj), j, _mm256_fmadd_ps(_mm256_set1_ps(f.di), i, _mm256_set1_ps(f.at))));
}

/// The frame of a perspective block whose node positions (relative to storage node (ref_x, ref_y)) are
/// lin.x / lin.w and lin.y / lin.w: positions go in as they are (the reference node is the frame's), and the
/// tile covers the projections of the block's corners, which bound its voxels' (a projection keeps convex hulls).
template <bool Tiled>
BlockFrame projective_frame(const VoxelBlock& block, const BlockLinearisation& lin, int ref_x, int ref_y, WindowLayout w,
                            const SplatGrid& grid, int slack = 0) {
    BlockFrame f;
    f.amp_per_value = _mm256_set1_ps(1.0f);  // the amplitudes come in per voxel
    std::optional<std::array<int, 4>> nodes;
    if (Tiled && active_count(block) >= kTileMinVoxels) {
        double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
        for (int c = 0; c < 8; ++c) {
            const double i = 7.0 * (c & 1), j = 7.0 * ((c >> 1) & 1), k = 7.0 * ((c >> 2) & 1);
            auto at = [&](const AffineInBlock& a) { return double(a.at) + a.di * i + a.dj * j + a.dk * k; };
            const double inv_w = 1.0 / at(lin.w), x = at(lin.x) * inv_w, y = at(lin.y) * inv_w;
            x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
        // One node wider on each side for the float positions' rounding (positions far off the tile's size: the grid).
        if (x1 - x0 < kTileFloats && y1 - y0 < kTileFloats)
            nodes = std::array<int, 4>{int(std::floor(x0)) - 1, int(std::floor(x1)) + 1, int(std::floor(y0)) - 1, int(std::floor(y1)) + 1};
    }
    place_region(f, ref_x, ref_y, nodes, w, grid, slack);
    return f;
}

/// The node positions (lx, ly) relative to the frame and amplitudes of eight voxels of a linearised block, each
/// amplitude its line scale times its value and `to_mass` of its form's determinant.
template <class ToMass>
inline void project_batch(const BlockLinearisation& lin, __m256 i, __m256 j, __m256 k, __m256 v, float density_scale,
                          ToMass to_mass, __m256& lx, __m256& ly, __m256& amp) {
    const __m256 inv_w = _mm256_div_ps(_mm256_set1_ps(1.0f), evaluate(lin.w, i, j, k));
    const __m256 qxx = evaluate(lin.qxx, i, j, k), qxy = evaluate(lin.qxy, i, j, k), qyy = evaluate(lin.qyy, i, j, k);
    const __m256 det = _mm256_fmsub_ps(qxx, qyy, _mm256_mul_ps(qxy, qxy));
    amp = _mm256_mul_ps(_mm256_mul_ps(evaluate(lin.line_scale, i, j, k), _mm256_set1_ps(density_scale)), _mm256_mul_ps(to_mass(det), v));
    lx = _mm256_mul_ps(evaluate(lin.x, i, j, k), inv_w);
    ly = _mm256_mul_ps(evaluate(lin.y, i, j, k), inv_w);
}

template <WindowKind Kind>
uint64_t splat_block_projective(const VoxelBlock& block, const ProjectiveBlock& p, const PhaseFootprintTable& table,
                                SplatGrid& grid, SplatScratch& scratch) {
    const WindowLayout w = window_layout<Kind>(table);
    const BlockLinearisation& lin = *p.lin;
    const BlockFrame f = projective_frame<Kind != WindowKind::Table>(block, lin, p.ref_x, p.ref_y, w, grid);
    float* tiles = f.region.tiled ? scratch.tile_copies() : nullptr;
    const TileFlush flush(f.region, tiles, grid);
    // The voxel's own mass: sampled tables hold another form's footprint (of determinant table_det), whose
    // integral is in proportion to 1 / sqrt(det); pixel-averaged ones hold weights that sum to one.
    const __m256 over = _mm256_set1_ps(p.table_det > 0 ? float(p.table_det) : 1.0f);
    auto to_mass = [over](__m256 det) { return _mm256_sqrt_ps(_mm256_div_ps(over, det)); };
    VoxelBatch b;
    uint64_t count = 0;
    for_each_batch(block, all_active(block), [](int) { return true; }, [&](__m256 i, __m256 j, __m256 k, __m256 v) {
        __m256 lx, ly, amp;
        project_batch(lin, i, j, k, v, p.density_scale, to_mass, lx, ly, amp);
        prepare(lx, ly, amp, f, w, b);
        b.live &= uint32_t(_mm256_movemask_ps(finite_non_zero(v)));
        count += __builtin_popcount(b.live);
        deposit<Kind>(b, table, w, f, tiles, grid);
    });
    scratch.taps += count * uint64_t(w.window) * uint64_t(w.window);
    return count;
}

/// A separable window (x row `wx`, already times the amplitude, and y column `wy`) added at `out`, row pitch
/// `pitch`, in whole rows of eight lanes.
template <class T>
inline void add_separable(T* out, size_t pitch, __m256 wx, const float* wy, int rows) {
    for (int j = 0; j < rows; ++j, out += pitch) accumulate8(out, _mm256_mul_ps(wx, _mm256_broadcast_ss(wy + j)));
}

/// The same tap by tap, clipped to the grid (windows that stick out of it).
void add_separable_clipped(SplatGrid& g, int col, int row, const float* wx, const float* wy, int window) {
    const int j0 = std::max(0, -row), j1 = std::min(window, g.rows() - row);
    const int i0 = std::max(0, -col), i1 = std::min(window, g.columns() - col);
    for (int j = j0; j < j1; ++j) {
        double* out = g.row(row + j) + col;
        for (int i = i0; i < i1; ++i) out[i] += double(wy[j]) * wx[i];
    }
}

/// Row `p` of a separable table's phases blended with the next by `a`.
inline __m256 blend_phases(const float* p, float a) {
    const __m256 at = _mm256_loadu_ps(p), next = _mm256_loadu_ps(p + SeparableFootprintTable::kMaxWindow);
    return _mm256_fmadd_ps(_mm256_set1_ps(a), _mm256_sub_ps(next, at), at);
}

uint64_t splat_separable(const VoxelBlock& block, const ProjectiveBlock& p, const SeparableFootprintTable& table, SplatGrid& grid,
                         SplatScratch& scratch) {
    constexpr int kPhases = SeparableFootprintTable::kPhases, kLanes = SeparableFootprintTable::kMaxWindow;
    // prepare() finds each window's corner and whether it lies inside; its phase blend is for 2-D tables, unused.
    const WindowLayout w{table.half_width(), table.window(), kLanes, 1, 0};
    const BlockFrame f = projective_frame<true>(block, *p.lin, p.ref_x, p.ref_y, w, grid, kLanes - table.window());
    float* tiles = f.region.tiled ? scratch.tile_copies() : nullptr;
    const TileFlush flush(f.region, tiles, grid);
    const __m256 one = _mm256_set1_ps(1.0f);
    auto to_mass = [one](__m256 det) { return _mm256_sqrt_ps(_mm256_div_ps(one, det)); };  // the footprint's integral, node^2
    VoxelBatch b;
    uint64_t count = 0;
    for_each_batch(block, all_active(block), [](int) { return true; }, [&](__m256 i, __m256 j, __m256 k, __m256 v) {
        __m256 lx, ly, amp;
        project_batch(*p.lin, i, j, k, v, p.density_scale, to_mass, lx, ly, amp);
        prepare(lx, ly, amp, f, w, b);
        b.live &= uint32_t(_mm256_movemask_ps(finite_non_zero(v)));
        count += __builtin_popcount(b.live);
        for (uint32_t todo = b.live; todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            const float sx = b.fx[l] * kPhases, sy = b.fy[l] * kPhases;
            const int px = std::min(kPhases - 1, int(sx)), py = std::min(kPhases - 1, int(sy));
            const __m256 wx = _mm256_mul_ps(blend_phases(table.x(px), sx - float(px)), _mm256_set1_ps(b.amp[l]));
            alignas(32) float wy[kLanes];
            _mm256_store_ps(wy, blend_phases(table.y(py), sy - float(py)));
            if (!((b.inside >> l) & 1)) {
                alignas(32) float lanes[kLanes];
                _mm256_store_ps(lanes, wx);
                add_separable_clipped(grid, f.region.col0 + b.col[l], f.region.row0 + b.row[l], lanes, wy, w.window);
            } else if (f.region.tiled) {
                add_separable(tile_copy(tiles, l) + size_t(b.row[l]) * f.region.pitch + b.col[l], size_t(f.region.pitch), wx, wy,
                              w.window);
            } else {
                add_separable(grid.row(0) + size_t(b.row[l]) * grid.columns() + b.col[l], size_t(grid.columns()), wx, wy, w.window);
            }
        }
    });
    scratch.taps += count * uint64_t(w.window) * uint64_t(w.window);
    return count;
}

#endif  // PCVR_AVX2

}  // namespace

uint64_t splat_block_separable(const VoxelBlock& block, const ProjectiveBlock& projected, const SeparableFootprintTable& table,
                               SplatGrid& grid, SplatScratch& scratch) {
#ifdef PCVR_AVX2
    return splat_separable(block, projected, table, grid, scratch);
#else
    return 0;  // the callers keep their per-voxel footprints without AVX2 (kProjectivePhases)
#endif
}

uint64_t splat_block_phases(const VoxelBlock& block, const OrthographicMapping& map, const PhaseFootprintTable& table,
                            const ViewProjection* clip_view, SplatGrid& grid, SplatScratch& scratch) {
#ifdef PCVR_AVX2
    return table.window() == 4 ? splat_block<WindowKind::Table4x4>(block, map, table, clip_view, grid, scratch)
           : table.is_bilinear_spread() ? splat_block<WindowKind::Tent2x2>(block, map, table, clip_view, grid, scratch)
                                        : splat_block<WindowKind::Table>(block, map, table, clip_view, grid, scratch);
#else
    uint64_t count = 0;
    const int h = table.half_width();
    for_each_voxel(block, [&](int offset, float v) {
        const Vec3 p = voxel_position(block, offset);
        if (clip_view && !ViewProjection::inside_clip_range(clip_view->to_clip(p))) return;
        const double x = map.node_x(p), y = map.node_y(p), node_x = std::floor(x), node_y = std::floor(y);
        deposit_clipped(grid, int(node_x) - h + 1, int(node_y) - h + 1, float(x - node_x), float(y - node_y),
                        map.amp_per_value * v, table);
        ++count;
    });
    return count;
#endif
}

uint64_t splat_block_phases(const VoxelBlock& block, const ProjectiveBlock& projected, const PhaseFootprintTable& table,
                            SplatGrid& grid, SplatScratch& scratch) {
#ifdef PCVR_AVX2
    return table.window() == 4 ? splat_block_projective<WindowKind::Table4x4>(block, projected, table, grid, scratch)
                               : splat_block_projective<WindowKind::Table>(block, projected, table, grid, scratch);
#else
    return 0;  // the callers keep their per-voxel footprints without AVX2 (projective_phases_available)
#endif
}

}  // namespace pcvr
