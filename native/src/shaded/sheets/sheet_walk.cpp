#include "shaded/sheets/sheet_walk.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "shaded/sheets/sheet_walk_state.h"

namespace pcvr {

void WalkStats::add(const WalkStats& o) {
    voxels_splatted += o.voxels_splatted;
    voxels_occluded += o.voxels_occluded;
    taps += o.taps;
    samples_classified += o.samples_classified;
    samples_shaded += o.samples_shaded;
    tiles_terminated += o.tiles_terminated;
    tile_sheets_composited += o.tile_sheets_composited;
    tile_sheets_skipped += o.tile_sheets_skipped;
    sheet_samples += o.sheet_samples;
    sheet_samples_skipped += o.sheet_samples_skipped;
    sampled_strides |= o.sampled_strides;
    seconds_sampling += o.seconds_sampling;
    seconds_splat += o.seconds_splat;
    seconds_post_convolution += o.seconds_post_convolution;
    seconds_shading += o.seconds_shading;
    first_sheet = std::min(first_sheet, o.first_sheet);
    last_sheet = std::max(last_sheet, o.last_sheet);
}

SheetWalker::SheetWalker() = default;
SheetWalker::~SheetWalker() = default;

size_t SheetWalker::continue_image(const SheetWalkSetup& setup, const PixelRect& rect, const float* image, const float* depth) {
    size_t opaque = 0;
    for (int y = 0; y < rect.height(); ++y) {
        const size_t row = size_t(rect.y0 + y) * setup.width + rect.x0;
        for (int x = 0; x < rect.width(); ++x) {
            const size_t p = size_t(y) * row_pitch_ + x;
            if (setup.mip) {
                maximum_[p] = image[row + x];
                continue;
            }
            const float* in = image + 4 * (row + x);
            red_[p] = in[0], green_[p] = in[1], blue_[p] = in[2], alpha_[p] = in[3];
            if (depth) depth_[p] = depth[row + x];
            opaque += alpha_[p] >= setup.opacity_cutoff ? 1 : 0;
        }
    }
    return opaque;
}

void SheetWalker::render(const SheetWalkSetup& setup, size_t tile, float* image, float* depth, WalkStats& stats,
                         RenderControl& control) {
    const TileSet& tiles = *setup.tiles;
    const std::vector<TileBlock>& blocks = tiles.blocks(tile);
    if (blocks.empty()) return;
    const PixelRect rect = tiles.rect(tile);
    const int tw = rect.width(), th = rect.height();
    const bool mip = setup.mip;
    const SheetLattice& sheets = setup.sheets;
    const float cutoff = setup.opacity_cutoff;
    const bool occlusion_culling = !mip && cutoff < 1.0f;

    // Each grid listed in the tile gets pixel sheets over the tile and its gradient halo, and each of
    // its layers a ring over the nodes their post-convolution reads.
    if (grids_.size() < setup.grids.size()) grids_.resize(setup.grids.size());
    if (layers_.size() < setup.layers.size()) layers_.resize(setup.layers.size());
    for (auto& g : grids_)
        if (g) g->used = false;
    for (auto& l : layers_)
        if (l) l->used = false;
    int ring_depth = 0;
    for (const TileBlock& b : blocks) {
        auto& layer_state = layers_[b.layer];
        if (!layer_state) layer_state = std::make_unique<LayerState>();
        if (layer_state->used) continue;
        const WalkLayer& wl = setup.layers[b.layer];
        auto& grid_state = grids_[wl.grid];
        if (!grid_state) grid_state = std::make_unique<GridState>();
        GridState& g = *grid_state;
        if (!g.used) {
            g.used = true;
            g.halo = setup.grids[wl.grid].gradient_step;
            g.x0 = rect.x0 - g.halo;
            g.y0 = rect.y0 - g.halo;
            g.width = tw + 2 * g.halo;
            g.height = th + 2 * g.halo;
            // Zero, padded: the tile's last vector of eight pixels may read past its row.
            g.cell_columns = (g.width + GridState::kCell - 1) / GridState::kCell;
            g.cell_rows = (g.height + GridState::kCell - 1) / GridState::kCell;
            for (int k = 0; k < GridState::kSlots; ++k) {
                // A cell's last vector may start past the row's end: padded by a cell.
                g.slots[k].assign(size_t(g.width) * g.height + GridState::kCell, 0.0f);
                g.boxes[k] = Box{};
                // Padded to whole vectors of eight cells (composite_sample tests eight at a time).
                g.cell_lo[k].assign(size_t(g.cell_columns) * g.cell_rows + 8, 0.0f);
                g.cell_hi[k].assign(size_t(g.cell_columns) * g.cell_rows + 8, 0.0f);
            }
        }
        LayerState& l = *layer_state;
        l.used = true;
        const int L = wl.view->stride();
        int nx0, ny0, nx1, ny1;
        if (wl.post_convolve) {
            nx0 = floor_div(g.x0, L) - 1, nx1 = floor_div(g.x0 + g.width - 1, L) + 2;
            ny0 = floor_div(g.y0, L) - 1, ny1 = floor_div(g.y0 + g.height - 1, L) + 2;
        } else {
            nx0 = g.x0, nx1 = g.x0 + g.width - 1, ny0 = g.y0, ny1 = g.y0 + g.height - 1;
        }
        // Wide enough that the windows of voxels that reach the tile fit whole: they take the fast path.
        const int margin = wl.view->window_margin();
        const Box needed{margin, margin, margin + nx1 - nx0, margin + ny1 - ny0};
        nx0 -= margin, ny0 -= margin, nx1 += margin, ny1 += margin;
        l.placement = {nx0, ny0, needed};
        // Sheets alive: from s (the walk's first) or s + 1 to the last one a voxel splatted for sheet
        // s + 2 reaches, s + 3 + 2 reach / spacing; two more for rounding.
        const int depth = int(std::ceil(2.0 * wl.view->depth_reach() / sheets.spacing)) + 7;
        ring_depth = std::max(ring_depth, depth);
        if (wl.sampler)
            l.ring.reset(1, 1, 1);  // nothing is splatted
        else
            l.ring.reset(nx1 - nx0 + 1, ny1 - ny0 + 1, depth);
        l.stride = L;
        l.post_convolve = wl.post_convolve;
        l.reach = wl.post_convolve ? L * wl.filter.reach_nodes() - 1 : 0;
        l.occlusion.disable();
    }

    const size_t tile_pixels = size_t(tw) * th;
    row_pitch_ = (size_t(tw) + 7) / 8 * 8;
    // Eight more: a run of eight pixels may start anywhere in the last row.
    for (auto* plane : {&red_, &green_, &blue_, &alpha_}) plane->assign(row_pitch_ * th + 8, 0.0f);
    depth_.assign(row_pitch_ * th + 8, INFINITY);
    if (mip) maximum_.assign(row_pitch_ * th + 8, setup.mip_background);
    size_t opaque = 0, opaque_at_rebuild = 0;
    if (setup.owned) opaque = continue_image(setup, rect, image, depth);
    // The occlusion map is rebuilt (its cost: the tile's pixels) each time this many more became opaque.
    const size_t rebuild_step = std::max<size_t>(256, tile_pixels / 64);

    std::vector<Active> active;
    size_t next_entry = 0;
    // Blocks are sorted by the depth where their kernels begin: the first one starts the walk two
    // sheets early, since the cubic between sheets s and s + 1 reaches s + 2.
    int64_t s = std::max<int64_t>(0, sheets.slab_of(blocks.front().front) - 2);
    int64_t open_sheet = s;  // the first sheet not yet post-convolved: deposits before it are dropped

    int64_t sheets_walked = 0;
    bool terminated = false;
    while (s < sheets.count) {
        if ((++sheets_walked & 15) == 0) control.throw_if_cancelled();

        // 1. Splat every voxel that reaches sheet s + 2: centre depth - reach < boundary(s + 3).
        auto t0 = Clock::now();
        const double splat_front = sheets.boundary(s + 3);
        while (next_entry < blocks.size() && blocks[next_entry].front < splat_front) active.push_back({next_entry++, 0});
        // In activation order, so that every node sums its contributions in the same order whichever
        // other blocks the tile lists (culled or not).
        size_t kept = 0;
        for (size_t a = 0; a < active.size(); ++a) {
            const TileBlock& tb = blocks[active[a].entry];
            if (const SheetSampler* sampler = setup.layers[tb.layer].sampler) {
                // Sampled: the block stays until no sheet still to fill is within its kernels' reach.
                if (tb.front + sampler->block_span > sheets.boundary(open_sheet)) active[kept++] = active[a];
                continue;
            }
            LayerState& l = *layers_[tb.layer];
            const SlabView& view = *setup.layers[tb.layer].view;
            const VoxelBlock& block = view.grid().blocks()[tb.block];
            const bool occlusion = occlusion_culling && l.occlusion.active();
            if (occlusion && l.occlusion.covered(l.ring_box(tb))) {
                // Whatever is left of the block lands on opaque pixels only.
                stats.voxels_occluded += view.voxels_left(block, active[a].next_rank, tb.splat);
                continue;
            }
            // The voxels whose kernels reach sheet s + 2 come first in depth order (planar depth; for
            // spherical sheets a bound, SlabView::limit_scale).
            const float limit = float((splat_front + view.depth_reach()) * tb.limit_scale - view.order_depth(block));
            const std::vector<float>& depth = view.depth_order().depth;
            int last = active[a].next_rank;
            while (last < VoxelBlock::kSize && depth[last] < limit) ++last;
            const DepositCounts n = view.deposit(block, active[a].next_rank, last, l.ring, l.placement, open_sheet,
                                                 occlusion ? &l.occlusion : nullptr, tb.splat);
            stats.voxels_splatted += n.splatted;
            stats.voxels_occluded += n.occluded;
            stats.taps += n.taps;
            active[a].next_rank = last;
            if (last < VoxelBlock::kSize) active[kept++] = active[a];
        }
        active.resize(kept);
        auto t1 = Clock::now();
        stats.seconds_splat += std::chrono::duration<double>(t1 - t0).count();

        // 2. Post-convolve sheet s + 2 of every layer into its grid's pixel sheet (after a start or a
        // jump, s and s + 1 too).
        const double sampling_before = stats.seconds_sampling;
        for (int64_t t = open_sheet; t <= s + 2; ++t) {
            for (auto& g : grids_)
                if (g && g->used) g->clear_slot(GridState::slot(t));
            for (size_t li = 0; li < layers_.size(); ++li) {
                if (!layers_[li] || !layers_[li]->used) continue;
                if (setup.layers[li].sampler)
                    sample_sheet(setup, uint32_t(li), t, blocks, active, rect, opaque > 0, stats);
                else
                    grids_[setup.layers[li].grid]->add_layer_sheet(t, *layers_[li], setup.layers[li].filter, scratch_);
            }
            if (setup.between_sheets())  // only the first of several samples reads the cells
                for (auto& g : grids_)
                    if (g && g->used) g->summarise(GridState::slot(t));
        }
        open_sheet = s + 3;
        auto t2 = Clock::now();
        // (sampled layers' sheets, filled here, count apart)
        stats.seconds_post_convolution += std::chrono::duration<double>(t2 - t1).count() - (stats.seconds_sampling - sampling_before);

        // 3. Classify, shade and composite from sheet s towards s + 1 (MIP: take the maximum at s).
        bool any = false;
        const bool between = setup.between_sheets();
        for (const auto& g : grids_) any |= g && g->used && g->reaches(s, between);
        if (any) {
            ++stats.tile_sheets_composited;
            stats.first_sheet = std::min(stats.first_sheet, s);
            stats.last_sheet = std::max(stats.last_sheet, s);
            const int samples = mip ? 1 : setup.samples_per_sheet;
            for (int j = 0; j < samples; ++j) {
                if (mip)
                    take_maximum(setup, rect, s);
                else
                    opaque += composite_sample(setup, rect, s, float(j) / float(samples), samples);
            }
        } else {
            ++stats.tile_sheets_skipped;
        }
        stats.seconds_shading += seconds_since(t2);

        // 4. An opaque tile is done; the occlusion map follows the opaque pixels.
        if (!mip && opaque == tile_pixels) {
            terminated = true;
            break;
        }
        if (occlusion_culling && opaque >= opaque_at_rebuild + rebuild_step) {
            opaque_at_rebuild = opaque;
            open_pixels_.count(tw, th, [&](int x, int y) { return alpha_[size_t(y) * row_pitch_ + x] >= cutoff; });
            for (size_t li = 0; li < layers_.size(); ++li) {
                if (!layers_[li] || !layers_[li]->used || setup.layers[li].sampler) continue;
                LayerState& l = *layers_[li];
                const int L = l.stride;
                // A node's value spreads through the post filter, then the in-sheet gradient's stencil.
                const int reach = l.reach + setup.grids[setup.layers[li].grid].gradient_step;
                l.occlusion.rebuild(open_pixels_, L, rect.x0 - L * l.placement.node_x0, rect.y0 - L * l.placement.node_y0, l.ring.columns(),
                                    l.ring.rows(), reach);
            }
        }

        // 5. Nothing left in the rings and nothing splatting: jump to the next block's first sheet.
        bool pending = !active.empty();
        for (const auto& g : grids_) pending |= g && g->used && (g->has(s) || g->has(s + 1) || g->has(s + 2));
        for (const auto& l : layers_) {
            if (!l || !l->used) continue;
            for (int k = 3; k < ring_depth && !pending; ++k) pending |= !l->ring.touched(s + k).empty();
        }
        if (!pending) {
            if (next_entry == blocks.size()) break;
            const int64_t next = sheets.slab_of(blocks[next_entry].front) - 2;
            if (next > s + 1) {
                stats.tile_sheets_skipped += uint64_t(next - s - 1);
                for (const auto& g : grids_)
                    if (g && g->used)
                        for (int k = 0; k < GridState::kSlots; ++k) g->clear_slot(k);
                s = open_sheet = next;
                continue;
            }
        }
        ++s;
    }
    if (terminated) ++stats.tiles_terminated;
    stats.samples_classified += samples_classified_;
    stats.samples_shaded += samples_shaded_;
    samples_classified_ = samples_shaded_ = 0;

    // The tile into the image.
    for (int y = 0; y < th; ++y) {
        const size_t row = size_t(rect.y0 + y) * setup.width + rect.x0;
        for (int x = 0; x < tw; ++x) {
            const size_t p = size_t(y) * row_pitch_ + x;
            if (mip) {
                image[row + x] = maximum_[p];
            } else {
                float* out = image + 4 * (row + x);
                out[0] = red_[p], out[1] = green_[p], out[2] = blue_[p], out[3] = alpha_[p];
                if (depth) depth[row + x] = depth_[p];
            }
        }
    }
}

}  // namespace pcvr
