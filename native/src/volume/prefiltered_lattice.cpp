#include "volume/prefiltered_lattice.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include <tbb/parallel_for.h>

#include "volume/brick_visibility.h"
#include "volume/value_levels.h"

namespace pcvr {

namespace {

/// One pass of the taps (w, 1 - 2 w, w) along an axis: for each of `planes` planes (`plane_step` apart,
/// in parallel), the rows of `length` contiguous elements `step` apart, `count` of them, each row
/// becoming the blend of itself and its neighbours (whole rows at a time, so that every pass reads the
/// lattice in order). The lattice's margin holds zeros, so the ends see zeros beyond them.
void blur_axis(std::vector<float>& values, size_t planes, size_t plane_step, int count, size_t step, size_t length, float w) {
    const float centre = 1.0f - 2.0f * w;
    tbb::parallel_for(size_t(0), planes, [&](size_t p) {
        std::vector<float> before(length, 0.0f), here(length);
        float* base = values.data() + p * plane_step;
        for (int e = 0; e < count; ++e) {
            float* row = base + size_t(e) * step;
            const float* after = e + 1 < count ? row + step : nullptr;
            std::copy(row, row + length, here.begin());
            for (size_t n = 0; n < length; ++n) row[n] = centre * here[n] + w * (before[n] + (after ? after[n] : 0.0f));
            before.swap(here);
        }
    });
}

/// The least (`Less`: std::less) or largest of `in` over windows of 2 reach + 1 along one axis of a
/// lattice of `shape` (k fastest), into `out`.
template <class Less>
void dilate_axis(const std::vector<float>& in, std::vector<float>& out, const std::array<int32_t, 3>& shape, int axis, int reach,
                 Less less) {
    const size_t sj = size_t(shape[2]), si = sj * size_t(shape[1]);
    const size_t step = axis == 0 ? si : axis == 1 ? sj : 1;
    const int n = shape[axis];
    // Every line along the axis: the other two coordinates.
    const int a = axis == 0 ? 1 : 0, b = axis == 2 ? 1 : 2;
    const size_t sa = a == 0 ? si : sj, sb = b == 1 ? sj : 1;
    tbb::parallel_for(0, shape[a], [&](int u) {
        for (int v = 0; v < shape[b]; ++v) {
            const size_t base = size_t(u) * sa + size_t(v) * sb;
            for (int e = 0; e < n; ++e) {
                float m = in[base + size_t(e) * step];
                for (int d = std::max(0, e - reach); d <= std::min(n - 1, e + reach); ++d) {
                    const float x = in[base + size_t(d) * step];
                    if (less(x, m)) m = x;
                }
                out[base + size_t(e) * step] = m;
            }
        }
    });
}

/// PrefilteredLattice::ranges and tight_ranges from its values.
void build_ranges(PrefilteredLattice& lattice) {
    constexpr int B = PrefilteredLattice::kBrick;
    const std::array<int32_t, 3> n = lattice.bricks = {(lattice.shape[0] + B - 1) / B, (lattice.shape[1] + B - 1) / B,
                                                       (lattice.shape[2] + B - 1) / B};
    const size_t count = size_t(n[0]) * n[1] * n[2];
    std::vector<float> lo(count), hi(count);
    const size_t si = lattice.stride_i(), sj = lattice.stride_j();
    tbb::parallel_for(0, n[0], [&](int bi) {
        for (int bj = 0; bj < n[1]; ++bj)
            for (int bk = 0; bk < n[2]; ++bk) {
                float least = INFINITY, most = -INFINITY;
                for (int i = B * bi; i < std::min(B * bi + B, lattice.shape[0]); ++i)
                    for (int j = B * bj; j < std::min(B * bj + B, lattice.shape[1]); ++j)
                        for (int k = B * bk; k < std::min(B * bk + B, lattice.shape[2]); ++k) {
                            const float v = lattice.values[size_t(i) * si + size_t(j) * sj + size_t(k)];
                            least = std::min(least, v), most = std::max(most, v);
                        }
                const size_t b = (size_t(bi) * n[1] + bj) * n[2] + bk;
                lo[b] = least, hi[b] = most;
            }
    });
    // Over the bricks within kTightRangeReach / kBrick of each, axis by axis, then as many more as make
    // kRangeReach (a window's extremes over a window's extremes are the wider window's).
    std::vector<float> scratch(count);
    auto dilate = [&](int reach) {
        for (int axis = 0; axis < 3; ++axis) {
            dilate_axis(lo, scratch, n, axis, reach, std::less<float>());
            lo.swap(scratch);
            dilate_axis(hi, scratch, n, axis, reach, std::greater<float>());
            hi.swap(scratch);
        }
    };
    constexpr int tight = PrefilteredLattice::kTightRangeReach / B, wide = PrefilteredLattice::kRangeReach / B;
    static_assert(tight <= wide);
    float lowest = INFINITY, most = -INFINITY;  // the same over every reach
    for (size_t b = 0; b < count; ++b) lowest = std::min(lowest, lo[b]), most = std::max(most, hi[b]);
    const ValueLevels levels = ValueLevels::spanning(lowest, most);
    lattice.range_lowest = levels.lowest, lattice.range_step = levels.step;
    auto quantise = [&](std::vector<uint16_t>& ranges) {
        ranges.assign(count + 1, 0);
        tbb::parallel_for(size_t(0), count, [&](size_t b) { ranges[b] = uint16_t(levels.below(lo[b]) | (levels.above(hi[b]) << 8)); });
    };
    dilate(tight);
    quantise(lattice.tight_ranges);
    if (wide > tight) dilate(wide - tight);
    quantise(lattice.ranges);
}

}  // namespace

PrefilteredLattice build_prefiltered_lattice(const std::vector<VoxelBlock>& blocks, const std::array<int32_t, 6>& box,
                                             float background, float blur) {
    constexpr int M = PrefilteredLattice::kMargin;
    PrefilteredLattice lattice;
    lattice.blur = blur;
    lattice.visibility = std::make_shared<BrickVisibilityCache>();
    for (int a = 0; a < 3; ++a) {
        lattice.origin[a] = box[a] - M;
        lattice.shape[a] = box[a + 3] - box[a] + 1 + 2 * M;
    }
    const size_t si = lattice.stride_i(), sj = lattice.stride_j();
    lattice.values.assign(si * size_t(lattice.shape[0]), 0.0f);
    // Blocks never overlap: each writes its own elements.
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        const VoxelBlock& block = blocks[b];
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            if (!block.active(offset)) continue;
            const float v = block.value(offset) - background;
            if (!std::isfinite(v)) continue;
            const int i = block.origin[0] + (offset >> 6) - lattice.origin[0];
            const int j = block.origin[1] + ((offset >> 3) & 7) - lattice.origin[1];
            const int k = block.origin[2] + (offset & 7) - lattice.origin[2];
            lattice.values[size_t(i) * si + size_t(j) * sj + size_t(k)] = v;
        }
    });
    if (blur == 0.0f) {
        build_ranges(lattice);
        return lattice;
    }
    // Separable: along k (rows of one element), then j and i (rows of whole k lines).
    const int ni = lattice.shape[0], nj = lattice.shape[1], nk = lattice.shape[2];
    blur_axis(lattice.values, size_t(ni) * nj, sj, nk, 1, 1, blur);
    blur_axis(lattice.values, size_t(ni), si, nj, sj, size_t(nk), blur);
    blur_axis(lattice.values, size_t(nj), sj, ni, si, size_t(nk), blur);
    build_ranges(lattice);
    return lattice;
}

}  // namespace pcvr
