/// @file sheet_walk_state.h
/// @brief What a SheetWalker keeps of one tile between the steps of its walk: each layer's ring and occlusion map
/// (LayerState), each grid's four post-convolved pixel sheets and their cell ranges (GridState).
///
/// Private to the walk's three sources, which share these states: the walk itself (sheet_walk.cpp), the sampled
/// layers' sheets (sheet_walk_sampling.cpp) and the samples classified, shaded and composited between sheets
/// (sheet_walk_compositing.cpp). Their members stay inline here, as they were in the one source they came from.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

#include "shaded/sheets/sheet_walk.h"

namespace pcvr {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

inline int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/// One layer's part of a tile: its ring of node sheets and its occlusion map.
struct SheetWalker::LayerState {
    bool used = false;
    SheetRing ring;
    RingPlacement placement;
    OcclusionMap occlusion;
    int stride = 1, reach = 0;  // reach: pixels a node's value spreads to
    bool post_convolve = true;

    /// The ring nodes a listed block's footprints can reach (a node of rounding on each side).
    Box ring_box(const TileBlock& b) const {
        auto node = [this](float pixel) { return std::clamp(double(pixel) / stride, -1e6, 1e6); };
        return Box{int(std::floor(node(b.min_x))) - placement.node_x0 - 1, int(std::floor(node(b.min_y))) - placement.node_y0 - 1,
                   int(std::ceil(node(b.max_x))) - placement.node_x0 + 1, int(std::ceil(node(b.max_y))) - placement.node_y0 + 1}
            .clipped({0, 0, ring.columns() - 1, ring.rows() - 1});
    }
};

/// One grid's part of a tile: its post-convolved sheets s - 1 to s + 2 (its layers add up in them).
struct SheetWalker::GridState {
    static constexpr int kSlots = 4;
    bool used = false;
    int halo = 1;                               // the in-sheet gradient's step (pixels beyond the tile)
    int x0 = 0, y0 = 0, width = 0, height = 0;  // post-convolved region: the tile and its halo
    std::vector<float> slots[kSlots];           // post-convolved sheet s in slot s mod 4, zero outside its box
    Box boxes[kSlots];                          // the pixels (slot coordinates) that may be non-zero

    /// Per cell of kCell x kCell slot pixels (cell (x / kCell, y / kCell)), the least and largest value of
    /// each slot (0 included: most of a cell may hold none), made once per sheet (summarise): the first
    /// sample between two sheets skips the cells where no value in their range may be visible without
    /// reading their pixels (an opaque bone function at 2048^2 leaves almost all of a sheet's box so).
    static constexpr int kCell = 8;
    int cell_columns = 0, cell_rows = 0;
    std::vector<float> cell_lo[kSlots], cell_hi[kSlots];

    size_t pitch() const { return size_t(width); }
    static int slot(int64_t s) { return int(s & (kSlots - 1)); }
    const float* sheet(int64_t s) const { return slots[slot(s)].data(); }
    const Box& box(int64_t s) const { return boxes[slot(s)]; }
    bool has(int64_t s) const { return !box(s).empty(); }
    /// Whether a sample from sheet s on can read anything: sheet s, and with samples between sheets
    /// (`between`) the cubic's s - 1 to s + 2.
    bool reaches(int64_t s, bool between) const { return has(s) || (between && (has(s - 1) || has(s + 1) || has(s + 2))); }

    /// The cell ranges of slot k, from its box (the cells outside hold only zeros).
    void summarise(int k) {
        std::fill(cell_lo[k].begin(), cell_lo[k].end(), 0.0f);
        std::fill(cell_hi[k].begin(), cell_hi[k].end(), 0.0f);
        const Box& b = boxes[k];
        if (b.empty()) return;
        // Whole cells' columns, eight pixels a vector (slot rows are padded past their end).
        for (int cy = b.y0 / kCell; cy <= b.y1 / kCell; ++cy)
            for (int cx = b.x0 / kCell; cx <= b.x1 / kCell; ++cx) {
                float8 lo = broadcast8(0.0f), hi = broadcast8(0.0f);
                for (int y = std::max(cy * kCell, b.y0); y <= std::min(cy * kCell + kCell - 1, b.y1); ++y) {
                    const float8 v = load8(slots[k].data() + size_t(y) * pitch() + size_t(cx) * kCell);
                    lo = min8(lo, v), hi = max8(hi, v);
                }
                float least = lo[0], most = hi[0];
                for (int l = 1; l < 8; ++l) least = std::min(least, lo[l]), most = std::max(most, hi[l]);
                cell_lo[k][size_t(cy) * cell_columns + cx] = least;
                cell_hi[k][size_t(cy) * cell_columns + cx] = most;
            }
    }

    /// Zeroes slot k where it may hold values.
    void clear_slot(int k) {
        const Box& b = boxes[k];
        for (int r = b.y0; r <= b.y1; ++r) std::fill_n(slots[k].data() + size_t(r) * pitch() + b.x0, b.x1 - b.x0 + 1, 0.0f);
        boxes[k] = Box{};
        std::fill(cell_lo[k].begin(), cell_lo[k].end(), 0.0f);
        std::fill(cell_hi[k].begin(), cell_hi[k].end(), 0.0f);
    }

    /// Adds layer sheet t, post-convolved where splats reached it, into slot t mod 4, and releases it.
    void add_layer_sheet(int64_t t, LayerState& layer, const PostFilter& filter, std::vector<float>& scratch) {
        const Box nodes = layer.ring.touched(t);
        if (nodes.empty()) return;
        const int L = layer.stride;
        const RingPlacement& at = layer.placement;
        // The pixels those nodes reach, in slot coordinates.
        const Box pixels = Box{L * (at.node_x0 + nodes.x0) - x0, L * (at.node_y0 + nodes.y0) - y0, L * (at.node_x0 + nodes.x1) - x0,
                               L * (at.node_y0 + nodes.y1) - y0}
                               .grown(layer.reach)
                               .clipped({0, 0, width - 1, height - 1});
        if (!pixels.empty()) {
            const int k = slot(t);
            float* out = slots[k].data() + size_t(pixels.y0) * pitch() + pixels.x0;
            const int w = pixels.x1 - pixels.x0 + 1, h = pixels.y1 - pixels.y0 + 1;
            if (layer.post_convolve) {
                const NodeSheet sheet{layer.ring.sheet(t), layer.ring.pitch(), at.node_x0, at.node_y0};
                post_convolve_region(sheet, filter, x0 + pixels.x0, y0 + pixels.y0, w, h, out, pitch(), scratch, true);
            } else {  // stride 1: the nodes are the pixels
                const float* in = layer.ring.sheet(t) + size_t(y0 + pixels.y0 - at.node_y0) * layer.ring.pitch() + (x0 + pixels.x0 - at.node_x0);
                for (int r = 0; r < h; ++r)
                    for (int c = 0; c < w; ++c) out[size_t(r) * pitch() + c] += in[size_t(r) * layer.ring.pitch() + c];
            }
            boxes[k].include(pixels);
        }
        layer.ring.release(t);
    }
};

}  // namespace pcvr
