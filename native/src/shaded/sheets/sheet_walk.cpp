#include "shaded/sheets/sheet_walk.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "shaded/classify/emission.h"

namespace pcvr {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

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

SheetWalker::SheetWalker() = default;
SheetWalker::~SheetWalker() = default;

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
            if (!mip && setup.samples_per_sheet > 1)  // only the first of several samples reads the cells
                for (auto& g : grids_)
                    if (g && g->used) g->summarise(GridState::slot(t));
        }
        open_sheet = s + 3;
        auto t2 = Clock::now();
        // (sampled layers' sheets, filled here, count apart)
        stats.seconds_post_convolution += std::chrono::duration<double>(t2 - t1).count() - (stats.seconds_sampling - sampling_before);

        // 3. Classify, shade and composite from sheet s towards s + 1 (MIP: take the maximum at s).
        bool any = false;
        const bool between = !mip && setup.samples_per_sheet > 1;
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

namespace {

/// Pixel positions of a run of eight pixels along a tile row, as lanes.
struct PixelLanes {
    float8 px;
    float py;
    int8x inside;  // lanes within the tile
};

/// Tile pixels x .. x + 7 of row y, those before `end` inside.
inline PixelLanes pixel_lanes(const PixelRect& rect, int x, int y, int end) {
    const float8 lane = lane_index8();
    return {float(rect.x0 + x) + lane, float(rect.y0 + y), lane < float(end - x)};
}

/// A slot's box in tile coordinates, within the tile.
inline Box tile_box(const Box& slot_box, int halo, const PixelRect& rect) {
    if (slot_box.empty()) return {};
    return Box{slot_box.x0 - halo, slot_box.y0 - halo, slot_box.x1 - halo, slot_box.y1 - halo}.clipped(
        {0, 0, rect.width() - 1, rect.height() - 1});
}

/// |grad density| per world unit from composite_sample's scale-free gradient, for gradient opacity
/// (ClassificationTable::extinction) and a clipped grid's weak gradients (sample_clip.h): there the frame
/// [per_pixel_x, per_pixel_y, along] was scaled by per_length = 1 / |along| (ppx its first column), and the
/// gradient's rows are those of its inverse times its determinant (from_x the first), while the sheets hold
/// density times the spacing. The true gradient is per_length gradient / determinant / spacing; dividing
/// by the determinant first keeps tiny and huge voxels within float's range. Out of line: without gradient
/// opacity or clipping the walk's loop stays as lean as it was.
[[gnu::noinline]] float8 gradient_magnitude(const Vec3x8& gradient, const Vec3x8& ppx, const Vec3x8& from_x, float8 per_length,
                                            float spacing) {
    const Vec3x8 times_slab = gradient * (per_length / dot(ppx, from_x));
    return sqrt8(dot(times_slab, times_slab)) * (1.0f / spacing);
}

}  // namespace

bool SheetWalkSetup::within_clip_everywhere(double u, double half) const {
    if (!sheets.spherical) {  // depth = (u - u at depth 0) k, between the latter's extremes over the image
        const SheetGeometry& g = *geometry;
        return (u - half - g.plane_u0_most) * g.plane_k >= near_depth && (u + half - g.plane_u0_least) * g.plane_k <= far_depth;
    }
    // depth = u / |M direction|, between the bounds of |M direction| over the image.
    return (u - half) / geometry->longest_metric_ray >= near_depth && (u + half) / geometry->least_metric_ray <= far_depth;
}

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
    const bool skip_transparent =
        sampler.may_skip(*setup.geometry, setup.sheets.spherical, middle, spacing, g.x0, g.y0, g.x0 + g.width - 1, g.y0 + g.height - 1);
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
                                                        end - cx, skip_transparent, slot + size_t(y) * g.pitch() + x0, x1 - x0 + 1);
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
    const bool skip_transparent = filter.overshoot() == 0.0 && sampler.may_skip(*setup.geometry, setup.sheets.spherical, middle, spacing,
                                                                               g.x0, g.y0, g.x0 + g.width - 1, g.y0 + g.height - 1, L * reach);
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
                                                        L * (ny0 + r), vectors, skip_transparent, nodes_.data() + size_t(r) * pitch + c,
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

void SheetWalker::take_maximum(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s) {
    const float spacing = float(setup.sheets.spacing);
    const double middle = setup.sheets.boundary(s) + 0.5 * setup.sheets.spacing;
    for (size_t gi = 0; gi < grids_.size(); ++gi) {
        if (!grids_[gi] || !grids_[gi]->used || !grids_[gi]->has(s)) continue;
        const GridState& g = *grids_[gi];
        const float *before = g.sheet(s - 1), *here = g.sheet(s), *after = g.sheet(s + 1);
        const Box box = tile_box(g.box(s), g.halo, rect);
        for (int y = box.y0; y <= box.y1; ++y)
            for (int x = box.x0; x <= box.x1; x += 8) {
                const PixelLanes p = pixel_lanes(rect, x, y, box.x1 + 1);
                const size_t i = size_t(y + g.halo) * g.pitch() + size_t(x + g.halo);
                const float8 m = load8(here + i), b = load8(before + i), a = load8(after + i);
                // A slab mean is lower than the peak inside it: at a local maximum along the ray, the
                // parabola through the three slab means locates the peak, and a parabola's slab mean
                // lies its curvature / 24 below its value (the box filter's second moment).
                const float8 curvature = 2.0f * m - b - a;
                const int8x peak_here = (m >= b) & (m >= a) & (curvature > 0);
                const float8 slope = a - b;
                const float8 safe = select8(peak_here, curvature, broadcast8(1.0f));
                // |slope| <= curvature at a peak: slope / (8 curvature) is at most 1/8, and the product cannot overflow.
                const float8 peak = m + select8(peak_here, slope * (slope / (8.0f * safe)) + curvature / 24.0f, broadcast8(0.0f));
                const SampleFrames f = sample_frames(*setup.geometry, setup.sheets.spherical, p.px, p.py, middle);
                float* most = maximum_.data() + size_t(y) * row_pitch_ + x;
                // Zero means no voxel reaches: empty, not a density of 0.
                const int8x counted = p.inside & (m != 0) & setup.within_clip(f.depth);
                const int8x kept = setup.grids[gi].clip ? counted & setup.grids[gi].clip->inside<float8>(f.position) : counted;
                const float8 density = peak * (1.0f / spacing) + setup.grids[gi].background;
                store8(most, select8(kept, max8(load8(most), density), load8(most)));
            }
    }
}

/// Catmull-Rom along the ray through four consecutive sheets' slab integrals, s - 1 to s + 2, at t
/// of the way from s to s + 1: their weights for the value and for its derivative in t. Linear
/// interpolation between two sheets leaves terraces where a sharp surface crosses them; the cubic
/// follows the surface between the sheets. Its value is clamped to the range of sheets s and s + 1:
/// no overshoot beside sharp edges, and a sample stays within what the two sheets around it hold,
/// which transfer-function culling relies on (unclamped, the cubic's 1/8 overshoot halved the blocks
/// culled on a CT head; clamped, peaks between sheets are flattened: the sheets sum to the X-ray to
/// 3e-3 instead of 7e-4 with several samples per sheet, at the same PSNR against the ray caster).
struct AlongRay {
    float value[4], slope[4];
    explicit AlongRay(float t) {
        const float t2 = t * t, t3 = t2 * t;
        value[0] = 0.5f * (-t + 2 * t2 - t3), value[1] = 0.5f * (2 - 5 * t2 + 3 * t3);
        value[2] = 0.5f * (t + 4 * t2 - 3 * t3), value[3] = 0.5f * (t3 - t2);
        slope[0] = 0.5f * (-1 + 4 * t - 3 * t2), slope[1] = 0.5f * (9 * t2 - 10 * t);
        slope[2] = 0.5f * (1 + 8 * t - 9 * t2), slope[3] = 0.5f * (3 * t2 - 2 * t);
    }
    float8 at(const float8 (&v)[4], const float (&w)[4]) const { return w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3]; }
    float8 value_at(const float8 (&v)[4]) const { return min8(max8(at(v, value), min8(v[1], v[2])), max8(v[1], v[2])); }
};

size_t SheetWalker::composite_sample(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s, float t, int samples) {
    const SheetGeometry& geo = *setup.geometry;
    const float spacing = float(setup.sheets.spacing), cutoff = setup.opacity_cutoff;
    // The sample lies t of the way from sheet s's middle to sheet s + 1's, and stands for 1 / samples of a slab.
    const double u = setup.sheets.boundary(s) + (0.5 + double(t)) * setup.sheets.spacing;

    // The grids with something at this sample, their sheets s - 1, s and s + 1, and the pixels where
    // any of them is not zero.
    struct Source {
        const GridState* grid;
        const ClassificationTable* classification;
        const Shader* shader;
        const SampleClip* clip;
        float background;
        const float *before, *here, *after, *beyond;  // sheets s - 1 to s + 2
    };
    // Sheet s alone at t = 0 with one sample per sheet; the cubic reaches s - 1 to s + 2 in between.
    // With several samples, every one of them lies between sheets s and s + 1's values (AlongRay clamps
    // it there): the first (t = 0) marks the vectors where some source may be visible in that range,
    // and the others visit only those, over the same sources and box.
    const bool between = samples > 1, marking = between && t == 0, marked = between && t > 0;
    const float per_spacing = 1.0f / spacing;
    Source sources[64];
    int source_count = 0;
    Box box;
    for (size_t gi = 0; gi < grids_.size() && source_count < 64; ++gi) {
        if (!grids_[gi] || !grids_[gi]->used) continue;
        const GridState& g = *grids_[gi];
        if (!g.reaches(s, between)) continue;
        const WalkGrid& wg = setup.grids[gi];
        sources[source_count++] = {&g,           wg.classification, wg.shader,       wg.clip,        wg.background,
                                   g.sheet(s - 1), g.sheet(s),        g.sheet(s + 1), g.sheet(s + 2)};
        box.include(tile_box(g.box(s), g.halo, rect));
        if (between)
            for (int64_t k : {s - 1, s + 1, s + 2}) box.include(tile_box(g.box(k), g.halo, rect));
    }
    const size_t vectors_per_row = box.empty() ? 0 : size_t(box.x1 - box.x0) / 8 + 1;
    if (marking) may_show_.assign(box.empty() ? 0 : vectors_per_row * size_t(box.y1 - box.y0 + 1), 0);
    // The first sample: per source, the cells where some value between sheets s and s + 1 may be
    // visible (GridState::summarise); a vector whose cells hold none for every source is skipped
    // unread, as the test below would (its ranges lie within the cells').
    if (marking)
        for (int k = 0; k < source_count; ++k) {
            const GridState& g = *sources[k].grid;
            const size_t cells = size_t(g.cell_columns) * g.cell_rows;
            std::vector<uint8_t>& shows = cell_shows_[size_t(k)];
            shows.resize(cells + 8);
            const float *lo_s = g.cell_lo[GridState::slot(s)].data(), *lo_t = g.cell_lo[GridState::slot(s + 1)].data();
            const float *hi_s = g.cell_hi[GridState::slot(s)].data(), *hi_t = g.cell_hi[GridState::slot(s + 1)].data();
            for (size_t c = 0; c < cells; c += 8) {
                const float8 lo = min8(load8(lo_s + c), load8(lo_t + c)) * per_spacing + sources[k].background;
                const float8 hi = max8(load8(hi_s + c), load8(hi_t + c)) * per_spacing + sources[k].background;
                const uint32_t bits = lane_mask(sources[k].classification->maybe_opaque_within(lo, hi));
                for (int l = 0; l < 8; ++l) shows[c + size_t(l)] = uint8_t((bits >> l) & 1);
            }
        }
    // Per row of the box, which of its vectors meet a cell that may show: made from the cells once
    // per row of cells (kCell pixel rows), so that a skipped vector costs a byte's test.
    int cached_cell_rows[64];
    std::fill_n(cached_cell_rows, source_count, INT32_MIN);
    auto update_row = [&](int y) {
        bool same = true;
        for (int k = 0; k < source_count; ++k) same &= floor_div(y + sources[k].grid->halo, GridState::kCell) == cached_cell_rows[k];
        if (same) return;
        row_may_show_.assign(vectors_per_row, 0);
        for (int k = 0; k < source_count; ++k) {
            const GridState& g = *sources[k].grid;
            const int cell_row = cached_cell_rows[k] = floor_div(y + g.halo, GridState::kCell);
            const uint8_t* shows = cell_shows_[size_t(k)].data() + size_t(cell_row) * g.cell_columns;
            const int first = std::max(0, floor_div(box.x0 + g.halo, GridState::kCell));
            const int last = std::min(g.cell_columns - 1, floor_div(box.x1 + g.halo, GridState::kCell));
            for (int c = first; c <= last; ++c) {
                if (!shows[c]) continue;
                // Cell c covers box columns from .. from + kCell - 1; vector v covers 8 v .. 8 v + 7.
                const int from = c * GridState::kCell - g.halo - box.x0;
                const int v0 = std::max(0, floor_div(from, 8)), v1 = std::min(int(vectors_per_row) - 1, floor_div(from + GridState::kCell - 1, 8));
                for (int v = v0; v <= v1; ++v) row_may_show_[size_t(v)] = 1;
            }
        }
    };

    // Sheets hold density times the slab's length in the sheet parameter, the same on every ray; its
    // world length (the opacity's) is the frame's. Samples away from the clip planes count in full:
    // the frames are only needed where something is classified.
    const double half_extent = 0.5 * setup.sheets.spacing / samples;
    const bool whole = setup.within_clip_everywhere(u, half_extent);
    const AlongRay along(t);

    size_t newly_opaque = 0;
    for (int y = box.y0; y <= box.y1; ++y) {
        if (marking) update_row(y);
        for (int x = box.x0; x <= box.x1; x += 8) {
            const size_t vector = size_t(y - box.y0) * vectors_per_row + size_t(x - box.x0) / 8;
            if (marked && !may_show_[vector]) continue;
            if (marking && !row_may_show_[size_t(x - box.x0) / 8]) continue;
            const size_t p = size_t(y) * row_pitch_ + x;
            const float8 alpha = load8(alpha_.data() + p);
            const PixelLanes lanes = pixel_lanes(rect, x, y, box.x1 + 1);
            int8x open = lanes.inside & (alpha < cutoff);
            if (!any8(open)) continue;
            // Each source's sheets and its sample, read once: most samples end here, where no source has
            // a density that may be visible. Sheets s and s + 1 bound the sample, so they decide most
            // vectors before the cubic's other two sheets are read (an opaque bone function leaves 97% of
            // the vectors at 2048^2 here).
            float8 sheet_values[64][4], raws[64];
            bool any = false;
            for (int k = 0; k < source_count; ++k) {
                const Source& src = sources[k];
                const size_t i = size_t(y + src.grid->halo) * src.grid->pitch() + size_t(x + src.grid->halo);
                const float8 here = load8(src.here + i), after = load8(src.after + i);
                const float8 lo = min8(here, after) * per_spacing + src.background, hi = max8(here, after) * per_spacing + src.background;
                if (!any8(open & ((here != 0) | (after != 0)) & src.classification->maybe_opaque_within(lo, hi))) {
                    raws[k] = broadcast8(0.0f);  // nothing visible: zero, as where no voxel reaches
                    continue;
                }
                if (marking) may_show_[vector] = 1;
                sheet_values[k][0] = load8(src.before + i), sheet_values[k][1] = here, sheet_values[k][2] = after;
                sheet_values[k][3] = load8(src.beyond + i);
                raws[k] = along.value_at(sheet_values[k]);
                any = any || any8(open & (raws[k] != 0) & src.classification->maybe_opaque(raws[k] * per_spacing + src.background));
            }
            if (!any) continue;
            samples_classified_ += uint64_t(__builtin_popcount(lane_mask(open)));
            const SampleFrames f = sample_frames(geo, setup.sheets.spherical, lanes.px, lanes.py, u);
            const float8 share = whole ? broadcast8(1.0f) : setup.clip_share(f.depth, f.depth_rate * float(half_extent));
            open &= share > 0;
            if (!any8(open)) continue;
            // The rows of the inverse of [per_pixel_x per_pixel_y along], times its determinant: they turn
            // derivatives per pixel and per unit of the sheet parameter into a world gradient.
            // The frame is divided by |along| first: products of three world lengths leave float's
            // range for voxels 1e-12 or 1e9 units wide, and a common factor leaves the direction alone.
            const float8 along_length = sqrt8(dot(f.along, f.along)), per_length = 1.0f / along_length;
            const Vec3x8 ahead = f.along * per_length, ppx = f.per_pixel_x * per_length, ppy = f.per_pixel_y * per_length;
            const Vec3x8 from_x = cross(ppy, ahead), from_y = cross(ahead, ppx), from_u = cross(ppx, ppy);
            const Vec3x8 to_eye = ahead * -1.0f;
            const float8 slab_length = spacing * along_length;  // world length of the slab along each ray
            float8 sigma_sum = broadcast8(0.0f);
            Vec3x8 glow{broadcast8(0.0f), broadcast8(0.0f), broadcast8(0.0f)};  // emitted radiance per world unit
            bool glowing = false;
            Vec3x8 lit_colours[64];
            float8 extinctions[64];
            int lit_count = 0;
            for (int k = 0; k < source_count; ++k) {
                const Source& src = sources[k];
                const GridState& g = *src.grid;
                const size_t i = size_t(y + g.halo) * g.pitch() + size_t(x + g.halo);
                const float8(&v)[4] = sheet_values[k];
                const float8 raw = raws[k];
                const float8 density = raw * per_spacing + src.background;
                int8x valid = open & (raw != 0) & src.classification->maybe_opaque(density);  // zero: no voxel reaches
                if (!any8(valid)) continue;
                // The share of the sample's stretch of ray inside the grid's clip region.
                const float8 kept = src.clip ? src.clip->share<float8>(f.position, f.along * float(half_extent)) : broadcast8(1.0f);
                valid &= kept > 0;
                if (!any8(valid)) continue;
                const ClassificationTable::Samples c = (*src.classification)(density);
                if (src.classification->has_emission()) {  // emits whether or not it absorbs
                    const ClassificationTable::Emissions e = src.classification->emission(density);
                    glow = glow + Vec3x8{e.red, e.green, e.blue} * select8(valid, kept, broadcast8(0.0f));
                    glowing = true;
                }
                valid &= c.extinction > 0;
                if (!any8(valid)) continue;
                // Density change per pixel right, per pixel down (interpolated linearly between the
                // sheets) and per unit of the sheet parameter (the cubic's slope; on a sheet the central
                // difference); common factors dropped: only the gradient's direction matters.
                const int L = g.halo;
                const size_t pitch = g.pitch();
                auto across = [&](const float* sheet, size_t step) { return load8(sheet + i + step) - load8(sheet + i - step); };
                const float8 g1 = (across(src.here, L) + t * (across(src.after, L) - across(src.here, L))) * (0.5f / L);
                const float8 g2 =
                    (across(src.here, L * pitch) + t * (across(src.after, L * pitch) - across(src.here, L * pitch))) * (0.5f / L);
                const float8 g3 = along.at(v, along.slope) * (1.0f / spacing);
                const Vec3x8 field_gradient = from_x * g1 + from_y * g2 + from_u * g3;
                const bool gradient_opacity = src.classification->has_gradient_opacity();
                const float8 magnitude = gradient_opacity || src.clip
                                             ? gradient_magnitude(field_gradient, ppx, from_x, per_length, spacing)
                                             : broadcast8(0.0f);
                float8 extinction = c.extinction;
                if (gradient_opacity) {
                    extinction = src.classification->extinction(density, magnitude);
                    valid &= extinction > 0;
                    if (!any8(valid)) continue;
                }
                // A cut face is lit by the plane's normal (sample_clip.h); gradient opacity read the field's.
                const Vec3x8 gradient =
                    src.clip ? src.clip->face_gradient<float8>(f.position, field_gradient,
                                                               src.clip->weak_gradient(magnitude, density - src.background))
                             : field_gradient;
                lit_colours[lit_count] = src.shader->shade({c.red, c.green, c.blue}, gradient, to_eye, f.position);
                extinctions[lit_count] = select8(valid, extinction * kept, broadcast8(0.0f));
                sigma_sum += extinctions[lit_count++];
            }
            // Overlapping grids mix as media do: extinctions add, colours weigh by their share of the
            // extinction (shares of at most one: colour times extinction could leave float's range).
            const int8x lit = sigma_sum > 0;
            if (!any8(lit) && !glowing) continue;
            samples_shaded_ += uint64_t(__builtin_popcount(lane_mask(lit & open)));
            Vec3x8 emission{broadcast8(0.0f), broadcast8(0.0f), broadcast8(0.0f)};
            if (lit_count == 1) {  // one medium's colour is its own, unweighed (no division on the way to the image)
                const Vec3x8& colour = lit_colours[0];
                emission = {select8(lit, colour.x, emission.x), select8(lit, colour.y, emission.y), select8(lit, colour.z, emission.z)};
            } else {
                const float8 per_sigma = select8(lit, 1.0f / select8(lit, sigma_sum, broadcast8(1.0f)), broadcast8(0.0f));
                for (int k = 0; k < lit_count; ++k) emission = emission + lit_colours[k] * (extinctions[k] * per_sigma);
            }
            const float8 opacity = 1.0f - exp8(-sigma_sum * slab_length * share * (1.0f / float(samples)));
            const float8 weight = select8(lit, (1.0f - alpha) * opacity, broadcast8(0.0f));
            store8(red_.data() + p, load8(red_.data() + p) + weight * emission.x);
            store8(green_.data() + p, load8(green_.data() + p) + weight * emission.y);
            store8(blue_.data() + p, load8(blue_.data() + p) + weight * emission.z);
            if (glowing) {  // apart, so that volumes without emission composite exactly as they did
                const float8 stretch = slab_length * share * (1.0f / float(samples));
                const float8 through = (1.0f - alpha) * emitted_length(sigma_sum, stretch, opacity);
                store8(red_.data() + p, load8(red_.data() + p) + through * glow.x);
                store8(green_.data() + p, load8(green_.data() + p) + through * glow.y);
                store8(blue_.data() + p, load8(blue_.data() + p) + through * glow.z);
            }
            const float8 new_alpha = alpha + weight;
            store8(alpha_.data() + p, new_alpha);
            const int8x half_way = (alpha < 0.5f) & (new_alpha >= 0.5f);
            if (any8(half_way)) store8(depth_.data() + p, select8(half_way, f.depth, load8(depth_.data() + p)));
            newly_opaque += __builtin_popcount(lane_mask(lanes.inside & (new_alpha >= cutoff) & (alpha < cutoff)));
        }
    }
    return newly_opaque;
}

}  // namespace pcvr
