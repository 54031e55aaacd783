#include "view/tile_set.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

namespace pcvr {

/// Tiles are squares of 128 to 256 pixels: several times a block's footprint, so that few voxels are
/// splatted by more than one tile (a voxel near a tile's edge is splatted by each tile it reaches), and
/// enough of them that threads share the work. At least 64 subgrid nodes (PCVR at magnification 4: 256
/// pixels), and as large as leaves some 32 tiles to an image: the CT head at 1024^2 on two threads
/// deposits 5.67M voxels in tiles of 128 pixels, 5.18M in tiles of 181 (bone: 3.16M and 2.92M), while
/// 512^2 in 4 tiles of 256 left a thread idle (tiles are taken busiest first, render_sheets). Not from
/// the thread count: tiles decide which voxels the occlusion map culls, and an image should not change
/// with the threads that rendered it.
int automatic_tile_size(int smallest_stride, int width, int height) {
    const double area = double(width) * height;
    return std::clamp(std::max(64 * smallest_stride, int(std::sqrt(area / 32.0))), 128, 256);
}

TileSet::TileSet(int width, int height, int tile_size)
    : width_(width), height_(height), tile_size_(tile_size),
      columns_((width + tile_size - 1) / tile_size), rows_((height + tile_size - 1) / tile_size),
      lists_(size_t(columns_) * rows_) {}

PixelRect TileSet::rect(size_t tile) const {
    const int tx = int(tile % columns_), ty = int(tile / columns_);
    return {tx * tile_size_, ty * tile_size_, std::min(width_, (tx + 1) * tile_size_), std::min(height_, (ty + 1) * tile_size_)};
}

void TileSet::add(uint32_t layer, uint32_t block, double front, double min_x, double min_y, double max_x, double max_y,
                  double reach, float limit_scale, const VoxelMask* splat) {
    const TileBlock entry{layer, block, front, float(min_x), float(min_y), float(max_x), float(max_y), limit_scale, splat};
    min_x -= reach, min_y -= reach, max_x += reach, max_y += reach;
    // Pixel centres sit at integer coordinates: the bounds touch pixels ceil(min) .. floor(max).
    auto tile_of = [&](double p, int count) { return int(std::clamp(std::floor(p / tile_size_), -1.0, double(count))); };
    const int tx0 = std::max(0, tile_of(std::ceil(min_x), columns_)), tx1 = std::min(columns_ - 1, tile_of(std::floor(max_x), columns_));
    const int ty0 = std::max(0, tile_of(std::ceil(min_y), rows_)), ty1 = std::min(rows_ - 1, tile_of(std::floor(max_y), rows_));
    for (int ty = ty0; ty <= ty1; ++ty)
        for (int tx = tx0; tx <= tx1; ++tx) lists_[size_t(ty) * columns_ + tx].push_back(entry);
}

void TileSet::sort() {
    tbb::parallel_for(size_t(0), lists_.size(), [&](size_t t) {
        std::sort(lists_[t].begin(), lists_[t].end(), [](const TileBlock& a, const TileBlock& b) {
            if (a.front != b.front) return a.front < b.front;
            return a.layer != b.layer ? a.layer < b.layer : a.block < b.block;
        });
    });
}

}  // namespace pcvr
