/// @file sheet_walk_sampling.cpp
/// @brief The walk's sampled layers (WalkLayer::sampler): which cells of a sheet the layer's active blocks reach
/// and a pixel not yet opaque reads, sampled there (sheet_sampling.h) at the pixels' stride, or at a coarser
/// subgrid stride and post-convolved to them.
///
/// Apart from the walk (sheet_walk.cpp), which only calls sample_sheet where it would post-convolve a splatted
/// layer's sheet: this is the sampling's bookkeeping (cells, wanted nodes, runs), not the order of the walk.
#include "shaded/sheets/sheet_walk.h"

#include <algorithm>

#include "shaded/sheets/sheet_walk_state.h"

namespace pcvr {

void SheetWalker::sample_sheet(const SheetWalkSetup& setup, uint32_t layer, int64_t t, const std::vector<TileBlock>& blocks,
                               const std::vector<Active>& active, const PixelRect& rect, bool some_opaque, WalkStats& stats) {
    const auto start = Clock::now();
    const SheetSampler& sampler = *setup.layers[layer].sampler;
    GridState& g = *grids_[setup.layers[layer].grid];
    constexpr int C = GridState::kCell;
    const double front = setup.sheets.boundary(t), back = setup.sheets.boundary(t + 1);
    // The cells the layer's blocks reach on sheet t (their pixel bounds and a pixel of rounding).
    sample_cells_.assign(size_t(g.cell_columns) * g.cell_rows, 0);
    // Blocks around the eye reach without bound (+-1e30): clamped before they become ints.
    auto pixel = [](float x) { return int(std::clamp(double(x), -1e6, 1e6)); };
    bool any = false;
    for (const Active& a : active) {
        const TileBlock& tb = blocks[a.entry];
        if (tb.layer != layer || tb.front >= back || tb.front + sampler.block_span <= front) continue;
        const Box pixels = Box{pixel(std::floor(tb.min_x)) - 1 - g.x0, pixel(std::floor(tb.min_y)) - 1 - g.y0,
                               pixel(std::ceil(tb.max_x)) + 1 - g.x0, pixel(std::ceil(tb.max_y)) + 1 - g.y0}
                               .clipped({0, 0, g.width - 1, g.height - 1});
        if (pixels.empty()) continue;
        for (int cy = pixels.y0 / C; cy <= pixels.y1 / C; ++cy)
            std::fill_n(sample_cells_.data() + size_t(cy) * g.cell_columns + pixels.x0 / C, pixels.x1 / C - pixels.x0 / C + 1, uint8_t(1));
        any = true;
    }
    if (!any) return;
    const float spacing = float(setup.sheets.spacing);
    const double middle = front + 0.5 * setup.sheets.spacing;
    // Whether a vector of eight slot pixels from (x, y) on is read by a pixel not yet opaque: itself or
    // its gradient's stencil (slot pixels are tile pixels shifted by the halo).
    const int h = g.halo, tw = rect.width(), th = rect.height();
    const float8 cutoff = broadcast8(setup.opacity_cutoff);
    // (With `last_row`, of any of rows y .. last_row.)
    auto read = [&](int x, int y, int last_row = -1) {
        if (!some_opaque) return true;
        // Tile pixels x - 2h .. x + 7 in rows y - 2h .. y: whole vectors, which may take in pixels past
        // the tile's edges (those only make it sample more; the planes are padded by a vector).
        const int x0 = std::max(0, x - 2 * h), x1 = std::min(tw - 1, x + GridState::kCell - 1);
        const int y0 = std::max(0, y - 2 * h), y1 = std::min(th - 1, std::max(y, last_row));
        if (x0 > x1 || y0 > y1) return false;
        for (int ty = y0; ty <= y1; ++ty)
            for (int tx = x0; tx <= x1; tx += 8)
                if (any8(load8(alpha_.data() + size_t(ty) * row_pitch_ + tx) < cutoff)) return true;
        return false;
    };
    float* slot = g.slots[GridState::slot(t)].data();
    Box& box = g.boxes[GridState::slot(t)];
    const int L = sampler.stride_at(*setup.geometry, setup.sheets.spherical, middle, setup.width, setup.height);
    stats.sampled_strides |= uint32_t(1) << L;
    if (L > 1) {
        sample_subgrid(setup, sampler, L, middle, spacing, g, read, slot, box, stats);
        stats.seconds_sampling += seconds_since(start);
        return;
    }
    const BrickVisibilityCache::Bits* skip =
        sampler.skip_bits(*setup.geometry, setup.sheets.spherical, middle, spacing, g.x0, g.y0, g.x0 + g.width - 1, g.y0 + g.height - 1);
    for (int y = 0; y < g.height; ++y) {
        const uint8_t* cells = sample_cells_.data() + size_t(y / C) * g.cell_columns;
        for (int cx = 0; cx < g.cell_columns;) {
            if (!cells[cx] || !read(C * cx, y)) {
                ++cx;
                continue;
            }
            int end = cx + 1;
            while (end < g.cell_columns && cells[end] && read(C * end, y)) ++end;
            // Vectors [cx, end), their pixels past the slot's width dropped.
            const int x0 = C * cx, x1 = std::min(C * end, g.width) - 1;
            const int interpolated = sampler.sample_run(*setup.geometry, setup.sheets.spherical, middle, spacing, g.x0 + x0, g.y0 + y,
                                                        end - cx, skip, slot + size_t(y) * g.pitch() + x0, x1 - x0 + 1);
            stats.sheet_samples += uint64_t(C) * uint64_t(interpolated);
            stats.sheet_samples_skipped += uint64_t(C) * uint64_t(end - cx - interpolated);
            box.include(Box{x0, y, x1, y});
            cx = end;
        }
    }
    stats.seconds_sampling += seconds_since(start);
}

template <class Read>
void SheetWalker::sample_subgrid(const SheetWalkSetup& setup, const SheetSampler& sampler, int L, double middle, float spacing,
                                 GridState& g, const Read& read, float* slot, Box& box, WalkStats& stats) {
    constexpr int C = GridState::kCell;
    const PostFilter& filter = sampler.post_filter(L);
    const int reach = filter.reach_nodes();
    // The subgrid over the slot (image pixel L n is node n) and the taps beyond it (a pixel reads nodes
    // -1 to +2 of its own, whatever the filter's weights there).
    constexpr int margin = PostFilter::kMarginNodes;
    const int nx0 = floor_div(g.x0, L) - margin, ny0 = floor_div(g.y0, L) - margin;
    const int columns = floor_div(g.x0 + g.width - 1, L) + margin + 1 - nx0, rows = floor_div(g.y0 + g.height - 1, L) + margin + 1 - ny0;
    // The cells whose pixels are wanted (marked, and read by a pixel not yet opaque in one of their rows),
    // and the nodes those pixels read.
    node_wanted_.assign(size_t(columns) * rows, 0);
    for (int cy = 0; cy < g.cell_rows; ++cy)
        for (int cx = 0; cx < g.cell_columns; ++cx) {
            uint8_t& cell = sample_cells_[size_t(cy) * g.cell_columns + cx];
            if (!cell) continue;
            cell = read(C * cx, C * cy, std::min(C * cy + C, g.height) - 1);
            if (!cell) continue;
            const int px0 = g.x0 + C * cx, px1 = g.x0 + std::min(C * cx + C, g.width) - 1;
            const int py0 = g.y0 + C * cy, py1 = g.y0 + std::min(C * cy + C, g.height) - 1;
            const int c0 = floor_div(px0, L) - 1 - nx0, c1 = floor_div(px1, L) + 2 - nx0;
            const int r0 = floor_div(py0, L) - 1 - ny0, r1 = floor_div(py1, L) + 2 - ny0;
            for (int r = r0; r <= r1; ++r) std::fill_n(node_wanted_.data() + size_t(r) * columns + c0, c1 - c0 + 1, uint8_t(1));
        }
    const size_t pitch = size_t(columns) + 8;  // a run's last vector may pass the row's end
    nodes_.assign(pitch * rows, 0.0f);
    // Skipped nodes hold 0, and the brick ranges hold 0 too: a pixel's value, a weighted mean of its
    // nodes, stays within them unless the filter has negative lobes (Catmull-Rom's overshoot), which
    // the ranges do not bound: then every wanted node is interpolated.
    const BrickVisibilityCache::Bits* skip =
        filter.overshoot() == 0.0 ? sampler.skip_bits(*setup.geometry, setup.sheets.spherical, middle, spacing, g.x0, g.y0, g.x0 + g.width - 1,
                                                      g.y0 + g.height - 1, L * reach)
                                  : nullptr;
    for (int r = 0; r < rows; ++r) {
        const uint8_t* wanted = node_wanted_.data() + size_t(r) * columns;
        for (int c = 0; c < columns;) {
            if (!wanted[c]) {
                ++c;
                continue;
            }
            int end = c + 1;
            while (end < columns && wanted[end]) ++end;
            const int vectors = (end - c + 7) / 8;
            const int interpolated = sampler.sample_run(*setup.geometry, setup.sheets.spherical, middle, spacing, L * (nx0 + c),
                                                        L * (ny0 + r), vectors, skip, nodes_.data() + size_t(r) * pitch + c,
                                                        end - c, L);
            stats.sheet_samples += uint64_t(8) * uint64_t(interpolated);
            stats.sheet_samples_skipped += uint64_t(8) * uint64_t(vectors - interpolated);
            c = end;
        }
    }
    // The wanted cells' pixels from the nodes, a row of cells at a time, each run of wanted cells as one region.
    const NodeSheet sheet{nodes_.data(), pitch, nx0, ny0};
    for (int cy = 0; cy < g.cell_rows; ++cy) {
        const uint8_t* cells = sample_cells_.data() + size_t(cy) * g.cell_columns;
        for (int cx = 0; cx < g.cell_columns;) {
            if (!cells[cx]) {
                ++cx;
                continue;
            }
            int end = cx + 1;
            while (end < g.cell_columns && cells[end]) ++end;
            const int x0 = C * cx, x1 = std::min(C * end, g.width) - 1, y0 = C * cy, y1 = std::min(C * cy + C, g.height) - 1;
            post_convolve_region(sheet, filter, g.x0 + x0, g.y0 + y0, x1 - x0 + 1, y1 - y0 + 1, slot + size_t(y0) * g.pitch() + x0,
                                 g.pitch(), scratch_, true);
            box.include(Box{x0, y0, x1, y1});
            cx = end;
        }
    }
}

}  // namespace pcvr
