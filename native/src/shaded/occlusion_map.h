/// @file occlusion_map.h
/// @brief Which nodes of a tile's sheet ring can no longer change a visible pixel (early ray termination
/// for splatting).
///
/// Once a pixel's accumulated opacity reaches the cutoff it takes no more samples, so splats that only
/// reach such pixels are wasted: the paper's occlusion map. For one grid in one tile, a ring node is
/// occluded when every pixel of the tile within `reach` pixels of it (the post-filter's support plus
/// the gradient stencil) is opaque; a voxel whose whole window lies on occluded nodes is not splatted.
/// Both questions are answered in constant time from summed-area tables of the pixels and nodes still
/// open, rebuilt whenever more pixels have become opaque.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "shaded/sheet_buffer.h"
#include "view/tile_set.h"

namespace pcvr {

class OcclusionMap {
public:
    /// `opaque(x, y)` says whether tile pixel (x, y) (relative to the tile) is opaque. Ring node (c, r)
    /// sits on tile pixel (stride * c - origin_x, stride * r - origin_y).
    template <class Opaque>
    void rebuild(int tile_width, int tile_height, Opaque opaque, int stride, int origin_x, int origin_y, int columns,
                 int rows, int reach) {
        // Open pixels, summed: open_[(y + 1) * (w + 1) + x + 1] = open pixels in [0, x] x [0, y].
        const int w = tile_width, h = tile_height;
        open_pixels_.assign(size_t(w + 1) * (h + 1), 0);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                open_pixels_[size_t(y + 1) * (w + 1) + x + 1] = (opaque(x, y) ? 0 : 1) + open_pixels_[size_t(y) * (w + 1) + x + 1] +
                                                                open_pixels_[size_t(y + 1) * (w + 1) + x] - open_pixels_[size_t(y) * (w + 1) + x];
        columns_ = columns;
        open_nodes_.assign(size_t(columns + 1) * (rows + 1), 0);
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < columns; ++c) {
                const int px = stride * c - origin_x, py = stride * r - origin_y;
                const int x0 = std::max(0, px - reach), x1 = std::min(w - 1, px + reach);
                const int y0 = std::max(0, py - reach), y1 = std::min(h - 1, py + reach);
                const bool open = x0 <= x1 && y0 <= y1 && sum(open_pixels_, w + 1, x0, y0, x1, y1) > 0;
                open_nodes_[size_t(r + 1) * (columns + 1) + c + 1] = (open ? 1 : 0) + open_nodes_[size_t(r) * (columns + 1) + c + 1] +
                                                                     open_nodes_[size_t(r + 1) * (columns + 1) + c] - open_nodes_[size_t(r) * (columns + 1) + c];
            }
        active_ = true;
    }

    void disable() { active_ = false; }
    bool active() const { return active_; }
    /// Every node of [c0, c1] x [r0, r1] (inclusive, within the ring) is occluded.
    bool covered(int c0, int r0, int c1, int r1) const {
        return active_ && c0 <= c1 && r0 <= r1 && sum(open_nodes_, columns_ + 1, c0, r0, c1, r1) == 0;
    }
    bool covered(const Box& nodes) const { return covered(nodes.x0, nodes.y0, nodes.x1, nodes.y1); }

private:
    static int32_t sum(const std::vector<int32_t>& table, int pitch, int x0, int y0, int x1, int y1) {
        return table[size_t(y1 + 1) * pitch + x1 + 1] - table[size_t(y0) * pitch + x1 + 1] - table[size_t(y1 + 1) * pitch + x0] +
               table[size_t(y0) * pitch + x0];
    }

    bool active_ = false;
    int columns_ = 0;
    std::vector<int32_t> open_pixels_, open_nodes_;
};

}  // namespace pcvr
