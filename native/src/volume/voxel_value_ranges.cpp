#include "volume/voxel_value_ranges.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "pcvr/errors.h"
#include "volume/block_lookup.h"
#include "volume/value_levels.h"

namespace pcvr {

namespace {

/// One axis of the box filter: `outer` runs of `inner` bytes, each the least (Max false) or the largest
/// of `taps` input runs `tap_pitch` apart (runs `in_pitch` apart in the input, `out_pitch` in the output).
/// Contiguous runs, and no aliasing, let the compiler take 32 bytes at a time.
template <bool Max>
void filter_axis(const uint8_t* __restrict in, uint8_t* __restrict out, int outer, int in_pitch, int out_pitch, int inner, int taps,
                 int tap_pitch) {
    for (int a = 0; a < outer; ++a) {
        const uint8_t* __restrict p = in + size_t(a) * in_pitch;
        uint8_t* __restrict o = out + size_t(a) * out_pitch;
        for (int b = 0; b < inner; ++b) o[b] = p[b];
        for (int t = 1; t < taps; ++t) {
            const uint8_t* __restrict q = p + size_t(t) * tap_pitch;
            for (int b = 0; b < inner; ++b) o[b] = Max ? std::max(o[b], q[b]) : std::min(o[b], q[b]);
        }
    }
}

}  // namespace

VoxelValueRanges build_voxel_value_ranges(const std::vector<VoxelBlock>& blocks, float background, int radius) {
    if (radius < 1 || radius > VoxelValueRanges::kMostRadius)
        throw InvalidArgument("voxel value ranges: the radius must be 1 to " + std::to_string(VoxelValueRanges::kMostRadius));
    constexpr int kDim = VoxelBlock::kDim, kSize = VoxelBlock::kSize;
    VoxelValueRanges out;
    out.radius = radius;
    double lowest = background, highest = background;
    for (const VoxelBlock& block : blocks)
        for (int offset = 0; offset < kSize; ++offset) {
            const float v = block.value(offset);
            if (!block.active(offset) || !std::isfinite(v)) continue;  // the splats skip these too
            lowest = std::min(lowest, double(v)), highest = std::max(highest, double(v));
            if (!block.values) break;  // a constant block: one value
        }
    const ValueLevels levels = ValueLevels::spanning(lowest, highest);
    out.lowest = levels.lowest, out.step = levels.step;

    // Each voxel's own levels (inactive and non-finite ones the background's).
    const uint8_t background_lo = levels.below(background), background_hi = levels.above(background);
    std::vector<uint8_t> own_lo(blocks.size() * kSize), own_hi(blocks.size() * kSize);
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        const VoxelBlock& block = blocks[b];
        for (int offset = 0; offset < kSize; ++offset) {
            const float v = block.value(offset);
            const bool counts = block.active(offset) && std::isfinite(v);
            own_lo[b * kSize + offset] = counts ? levels.below(v) : background_lo;
            own_hi[b * kSize + offset] = counts ? levels.above(v) : background_hi;
        }
    });

    const BlockLookup lookup(blocks);

    // The blocks by chunk of kChunk^3 voxels (4^3 blocks): a chunk's window (the chunk and `radius`
    // voxels around it) is filled from the blocks in and around it, the background where there are
    // none, then filtered by the box's least and largest one axis at a time, the slowest first (each
    // pass runs over contiguous bytes). Per chunk rather than per block: a block's window of side
    // 8 + 2 radius read each voxel some 20 times over at radius 7, a chunk's about 3 times.
    constexpr int kChunk = 32;
    std::map<std::array<int32_t, 3>, std::vector<size_t>> chunks;
    for (size_t b = 0; b < blocks.size(); ++b) {
        const auto& o = blocks[b].origin;
        chunks[{o[0] >> 5, o[1] >> 5, o[2] >> 5}].push_back(b);  // floor(o / kChunk) for negative origins too
    }
    std::vector<const std::pair<const std::array<int32_t, 3>, std::vector<size_t>>*> chunk_list;
    for (const auto& c : chunks) chunk_list.push_back(&c);

    out.lo.resize(blocks.size() * kSize);
    out.hi.resize(blocks.size() * kSize);
    const int side = kChunk + 2 * radius, taps = 2 * radius + 1, rings = (radius + kDim - 1) / kDim;
    const int pitch = (side + 31) / 32 * 32;  // rows along k padded to whole vectors of 32 bytes
    const size_t plane = size_t(side) * pitch;
    struct Scratch {
        std::vector<uint8_t> window, along_i, along_j, result;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    tbb::parallel_for(size_t(0), chunk_list.size(), [&](size_t c) {
        Scratch& s = scratch.local();
        s.window.resize(plane * side);
        s.along_i.resize(kChunk * plane);
        s.along_j.resize(size_t(kChunk) * kChunk * pitch);
        s.result.resize(size_t(kChunk) * kChunk * kChunk);
        const std::array<int32_t, 3> chunk{chunk_list[c]->first[0] * kChunk, chunk_list[c]->first[1] * kChunk,
                                           chunk_list[c]->first[2] * kChunk};
        for (int end = 0; end < 2; ++end) {
            const std::vector<uint8_t>& own = end == 0 ? own_lo : own_hi;
            uint8_t* window = s.window.data();
            std::fill(s.window.begin(), s.window.end(), end == 0 ? background_lo : background_hi);
            const int first_block = -rings, last_block = kChunk / kDim + rings;
            for (int bx = first_block; bx < last_block; ++bx)
                for (int by = first_block; by < last_block; ++by)
                    for (int bz = first_block; bz < last_block; ++bz) {
                        const int64_t n = lookup.find({chunk[0] + bx * kDim, chunk[1] + by * kDim, chunk[2] + bz * kDim});
                        if (n < 0) continue;
                        // The block's voxel (x, y, z) sits at window (at[0] + x, at[1] + y, at[2] + z).
                        const int at[3] = {bx * kDim + radius, by * kDim + radius, bz * kDim + radius};
                        int from[3], to[3];
                        for (int a = 0; a < 3; ++a) from[a] = std::max(0, -at[a]), to[a] = std::min(kDim, side - at[a]);
                        const uint8_t* voxels = own.data() + size_t(n) * kSize;
                        for (int x = from[0]; x < to[0]; ++x)
                            for (int y = from[1]; y < to[1]; ++y) {
                                uint8_t* row = window + size_t(at[0] + x) * plane + size_t(at[1] + y) * pitch + at[2];
                                const uint8_t* voxel_row = voxels + (x * kDim + y) * kDim;
                                if (from[2] == 0 && to[2] == kDim)
                                    std::memcpy(row, voxel_row, kDim);
                                else
                                    std::copy(voxel_row + from[2], voxel_row + to[2], row + from[2]);
                            }
                    }
            auto filter = [&](auto max) {
                constexpr bool kMax = decltype(max)::value;
                // along i: [32][side][pitch] from the window's [side][side][pitch]
                filter_axis<kMax>(window, s.along_i.data(), kChunk, int(plane), int(plane), int(plane), taps, int(plane));
                // along j: [32][32][pitch] from [32][side][pitch]
                for (int i = 0; i < kChunk; ++i)
                    filter_axis<kMax>(s.along_i.data() + i * plane, s.along_j.data() + size_t(i) * kChunk * pitch, kChunk, pitch, pitch,
                                      pitch, taps, pitch);
                // along k: [32][32][32] from [32][32][pitch]
                filter_axis<kMax>(s.along_j.data(), s.result.data(), kChunk * kChunk, pitch, kChunk, kChunk, taps, 1);
            };
            if (end == 0)
                filter(std::false_type{});
            else
                filter(std::true_type{});
            for (size_t b : chunk_list[c]->second) {
                const auto& o = blocks[b].origin;
                const int x0 = o[0] - chunk[0], y0 = o[1] - chunk[1], z0 = o[2] - chunk[2];
                uint8_t* dest = (end == 0 ? out.lo : out.hi).data() + b * kSize;
                for (int x = 0; x < kDim; ++x)
                    for (int y = 0; y < kDim; ++y)
                        std::memcpy(dest + (x * kDim + y) * kDim, s.result.data() + (size_t(x0 + x) * kChunk + (y0 + y)) * kChunk + z0, kDim);
            }
        }
    });
    return out;
}

}  // namespace pcvr
