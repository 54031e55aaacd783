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

#include "shaded/sheets/sheet_buffer.h"
#include "view/tile_set.h"

namespace pcvr {

/// A tile's pixels not yet opaque, summed over rectangles (a summed-area table): counted once each
/// time more pixels turn opaque, for every layer's occlusion map.
class OpenPixels {
public:
    /// `opaque(x, y)` says whether tile pixel (x, y) (relative to the tile) is opaque.
    template <class Opaque>
    void count(int tile_width, int tile_height, Opaque opaque) {
        width_ = tile_width, height_ = tile_height;
        const size_t pitch = size_t(width_) + 1;
        sums_.assign(pitch * (height_ + 1), 0);  // sums_[(y + 1) * pitch + x + 1]: open pixels in [0, x] x [0, y]
        for (int y = 0; y < height_; ++y) {
            int32_t row = 0;
            for (int x = 0; x < width_; ++x) {
                row += opaque(x, y) ? 0 : 1;
                sums_[size_t(y + 1) * pitch + x + 1] = sums_[size_t(y) * pitch + x + 1] + row;
            }
        }
    }
    int width() const { return width_; }
    int height() const { return height_; }
    /// Open pixels in [x0, x1] x [y0, y1] (inclusive, within the tile).
    int32_t in(int x0, int y0, int x1, int y1) const { return sum(sums_, width_ + 1, x0, y0, x1, y1); }

    static int32_t sum(const std::vector<int32_t>& table, int pitch, int x0, int y0, int x1, int y1) {
        return table[size_t(y1 + 1) * pitch + x1 + 1] - table[size_t(y0) * pitch + x1 + 1] - table[size_t(y1 + 1) * pitch + x0] +
               table[size_t(y0) * pitch + x0];
    }

private:
    int width_ = 0, height_ = 0;
    std::vector<int32_t> sums_;
};

class OcclusionMap {
public:
    /// From the tile's open pixels: ring node (c, r) sits on tile pixel (stride * c - origin_x,
    /// stride * r - origin_y), and is occluded when no pixel within `reach` of it is open.
    void rebuild(const OpenPixels& open, int stride, int origin_x, int origin_y, int columns, int rows, int reach) {
        const int w = open.width(), h = open.height();
        columns_ = columns;
        open_nodes_.assign(size_t(columns + 1) * (rows + 1), 0);
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < columns; ++c) {
                const int px = stride * c - origin_x, py = stride * r - origin_y;
                const int x0 = std::max(0, px - reach), x1 = std::min(w - 1, px + reach);
                const int y0 = std::max(0, py - reach), y1 = std::min(h - 1, py + reach);
                const bool is_open = x0 <= x1 && y0 <= y1 && open.in(x0, y0, x1, y1) > 0;
                open_nodes_[size_t(r + 1) * (columns + 1) + c + 1] = (is_open ? 1 : 0) + open_nodes_[size_t(r) * (columns + 1) + c + 1] +
                                                                     open_nodes_[size_t(r + 1) * (columns + 1) + c] - open_nodes_[size_t(r) * (columns + 1) + c];
            }
        active_ = true;
    }

    void disable() { active_ = false; }
    bool active() const { return active_; }
    /// Every node of [c0, c1] x [r0, r1] (inclusive, within the ring) is occluded.
    bool covered(int c0, int r0, int c1, int r1) const {
        return active_ && c0 <= c1 && r0 <= r1 && OpenPixels::sum(open_nodes_, columns_ + 1, c0, r0, c1, r1) == 0;
    }
    bool covered(const Box& nodes) const { return covered(nodes.x0, nodes.y0, nodes.x1, nodes.y1); }

private:
    bool active_ = false;
    int columns_ = 0;
    std::vector<int32_t> open_nodes_;
};

}  // namespace pcvr
