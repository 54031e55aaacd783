/// @file tile_set.h
/// @brief The image cut into square tiles that render independently, each listing the voxel blocks whose
/// footprints reach it, nearest first.
///
/// Tiles are the sheet renderer's unit of parallel work: one thread walks a tile's sheets front to back,
/// so occlusion is an early exit per tile and the image is the same for any number of threads. A block
/// whose footprints reach several tiles is listed in each and splatted by each, clipped to the tile:
/// tiles a few times wider than a block's footprint keep that repeated work small.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

/// The sheet renderer's tile side for an image of width x height pixels whose finest splatted stride is
/// `smallest_stride`: 128 to 256 pixels (why: tile_set.cpp).
int automatic_tile_size(int smallest_stride, int width, int height);

/// Pixels [x0, x1) x [y0, y1).
struct PixelRect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    int width() const { return x1 - x0; }
    int height() const { return y1 - y0; }
};

struct TileBlock {
    uint32_t layer;  ///< the grid and stride it is splatted at (the renderer's list of layers)
    uint32_t block;  ///< index into that grid's blocks()
    double front;    ///< sheet parameter where the block's kernels begin (SlabView::front)
    float min_x, min_y, max_x, max_y;  ///< pixels its footprints can reach
    float limit_scale = 1;  ///< SlabView::limit_scale of the block
    const VoxelMask* splat = nullptr;  ///< the voxels to splat (transparency culling); null: every active one
};

class TileSet {
public:
    TileSet(int width, int height, int tile_size);

    int tile_size() const { return tile_size_; }
    size_t size() const { return lists_.size(); }
    PixelRect rect(size_t tile) const;

    /// Lists a block in every tile that the pixel bounds [min_x, max_x] x [min_y, max_y], widened by
    /// `reach` pixels, overlap.
    void add(uint32_t layer, uint32_t block, double front, double min_x, double min_y, double max_x, double max_y, double reach,
             float limit_scale = 1.0f, const VoxelMask* splat = nullptr);
    /// Orders each tile's blocks nearest first (ties by layer, then block: deterministic).
    void sort();
    const std::vector<TileBlock>& blocks(size_t tile) const { return lists_[tile]; }

private:
    int width_, height_, tile_size_, columns_, rows_;
    std::vector<std::vector<TileBlock>> lists_;
};

}  // namespace pcvr
