// Grid::voxel_value_ranges' builder against the box's least and largest value found voxel by voxel.
#include <cmath>
#include <vector>

#include "pcvr/errors.h"
#include "random_blocks.h"
#include "unit_test.h"
#include "volume/voxel_value_ranges.h"

using namespace pcvr;


TEST(voxel_value_ranges_hold_each_box_within_a_level) {
    const RandomBlocks data;
    for (int radius : {1, 3, 9}) {
        const VoxelValueRanges r = build_voxel_value_ranges(data.blocks, data.background, radius);
        CHECK(r.radius == radius);
        CHECK(r.lo.size() == data.blocks.size() * VoxelBlock::kSize);
        int mismatches = 0;
        for (size_t b = 0; b < data.blocks.size(); ++b)
            for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
                const auto& o = data.blocks[b].origin;
                const int i = o[0] + (offset >> 6), j = o[1] + ((offset >> 3) & 7), k = o[2] + (offset & 7);
                float lo = INFINITY, hi = -INFINITY;
                for (int di = -radius; di <= radius; ++di)
                    for (int dj = -radius; dj <= radius; ++dj)
                        for (int dk = -radius; dk <= radius; ++dk) {
                            const float v = data.at(i + di, j + dj, k + dk);
                            lo = std::min(lo, v), hi = std::max(hi, v);
                        }
                const double low = r.value(r.lo[b * VoxelBlock::kSize + offset]), high = r.value(r.hi[b * VoxelBlock::kSize + offset]);
                // Rounded outwards, by less than a level.
                mismatches += !(low <= lo && lo - low < r.step && high >= hi && high - hi < r.step);
            }
        CHECK(mismatches == 0);
    }
}

TEST(voxel_value_ranges_refuse_radii_they_do_not_build) {
    const RandomBlocks data;
    for (int radius : {0, VoxelValueRanges::kMostRadius + 1}) {
        bool refused = false;
        try {
            build_voxel_value_ranges(data.blocks, data.background, radius);
        } catch (const InvalidArgument&) {
            refused = true;
        }
        CHECK(refused);
    }
}
