// Grid::prefiltered_lattice's builder against the lattice worked out element by element: the voxels less
// the background, the three-tap blur along each axis, and brick ranges holding everything within their reach.
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "random_blocks.h"
#include "unit_test.h"
#include "volume/prefiltered_lattice.h"

using namespace pcvr;

namespace {

/// The active voxels' inclusive index box.
std::array<int32_t, 6> active_box(const RandomBlocks& data) {
    std::array<int32_t, 6> box{INT32_MAX, INT32_MAX, INT32_MAX, INT32_MIN, INT32_MIN, INT32_MIN};
    for (const VoxelBlock& b : data.blocks)
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            if (!b.active(offset)) continue;
            const int at[3] = {b.origin[0] + (offset >> 6), b.origin[1] + ((offset >> 3) & 7), b.origin[2] + (offset & 7)};
            for (int a = 0; a < 3; ++a) box[a] = std::min(box[a], at[a]), box[a + 3] = std::max(box[a + 3], at[a]);
        }
    return box;
}

struct Expected {
    std::array<int32_t, 3> shape;
    std::vector<double> values;
    double at(int i, int j, int k) const {
        if (i < 0 || j < 0 || k < 0 || i >= shape[0] || j >= shape[1] || k >= shape[2]) return 0.0;
        return values[(size_t(i) * shape[1] + j) * shape[2] + k];
    }
};

}  // namespace

TEST(prefiltered_lattice_blurs_the_voxels_less_the_background) {
    const RandomBlocks data;
    const std::array<int32_t, 6> box = active_box(data);
    for (float w : {0.0f, 0.07f}) {
        const PrefilteredLattice lattice = build_prefiltered_lattice(data.blocks, box, data.background, w);
        const int M = PrefilteredLattice::kMargin;
        Expected e{lattice.shape, {}};
        for (int a = 0; a < 3; ++a) CHECK(lattice.origin[a] == box[a] - M && lattice.shape[a] == box[a + 3] - box[a] + 1 + 2 * M);
        // Unblurred: the voxel less the background (inactive and non-finite voxels: 0), then the taps axis by axis.
        e.values.resize(lattice.values.size());
        for (int i = 0; i < e.shape[0]; ++i)
            for (int j = 0; j < e.shape[1]; ++j)
                for (int k = 0; k < e.shape[2]; ++k)
                    e.values[(size_t(i) * e.shape[1] + j) * e.shape[2] + k] =
                        data.at(lattice.origin[0] + i, lattice.origin[1] + j, lattice.origin[2] + k) - data.background;
        for (int axis = 0; axis < 3; ++axis) {
            Expected next = e;
            for (int i = 0; i < e.shape[0]; ++i)
                for (int j = 0; j < e.shape[1]; ++j)
                    for (int k = 0; k < e.shape[2]; ++k) {
                        const int d[3] = {axis == 0, axis == 1, axis == 2};
                        next.values[(size_t(i) * e.shape[1] + j) * e.shape[2] + k] =
                            (1 - 2 * double(w)) * e.at(i, j, k) + double(w) * (e.at(i - d[0], j - d[1], k - d[2]) + e.at(i + d[0], j + d[1], k + d[2]));
                    }
            e = next;
        }
        double worst = 0;
        for (size_t n = 0; n < e.values.size(); ++n) worst = std::max(worst, std::abs(e.values[n] - lattice.values[n]));
        CHECK(worst < 1e-4);

        // Each brick's levels hold every element within its set's reach (kRangeReach, kTightRangeReach) of it,
        // rounded outwards by at most a level and a half.
        const int B = PrefilteredLattice::kBrick;
        for (const auto& [ranges, R] : {std::pair{&lattice.ranges, PrefilteredLattice::kRangeReach},
                                        std::pair{&lattice.tight_ranges, PrefilteredLattice::kTightRangeReach}}) {
            int mismatches = 0;
            for (int bi = 0; bi < lattice.bricks[0]; ++bi)
                for (int bj = 0; bj < lattice.bricks[1]; ++bj)
                    for (int bk = 0; bk < lattice.bricks[2]; ++bk) {
                        double lo = INFINITY, hi = -INFINITY;
                        for (int i = B * bi - R; i < B * bi + B + R; ++i)
                            for (int j = B * bj - R; j < B * bj + B + R; ++j)
                                for (int k = B * bk - R; k < B * bk + B + R; ++k) {
                                    if (i < 0 || j < 0 || k < 0 || i >= e.shape[0] || j >= e.shape[1] || k >= e.shape[2]) continue;
                                    const double v = lattice.values[(size_t(i) * e.shape[1] + j) * e.shape[2] + k];
                                    lo = std::min(lo, v), hi = std::max(hi, v);
                                }
                        const uint16_t levels = (*ranges)[(size_t(bi) * lattice.bricks[1] + bj) * lattice.bricks[2] + bk];
                        const double low = lattice.range_lowest + (levels & 255) * double(lattice.range_step);
                        const double high = lattice.range_lowest + (levels >> 8) * double(lattice.range_step);
                        const double step = lattice.range_step;
                        mismatches += !(low <= lo + 1e-6 && lo - low < 1.5 * step && high >= hi - 1e-6 && high - hi < 1.5 * step);
                    }
            CHECK(mismatches == 0);
            CHECK(ranges->size() == size_t(lattice.bricks[0]) * lattice.bricks[1] * lattice.bricks[2] + 1);
        }
    }
}
