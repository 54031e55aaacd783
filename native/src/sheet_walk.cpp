#include "sheet_walk.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

namespace pcvr {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

int floor_div(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
Vec3f cross3(const Vec3f& a, const Vec3f& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3f operator+(const Vec3f& a, const Vec3f& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3f operator*(const Vec3f& a, float s) { return {a.x * s, a.y * s, a.z * s}; }

/// Pixels beyond a tile whose post-convolved values the tile reads: one subgrid node on each side.
int gradient_halo(const WalkGrid& g) { return g.view->stride(); }

/// How far (pixels) a ring node's value spreads on the tile's pixels, gradients included.
int node_reach(const WalkGrid& g) {
    const int L = g.view->stride();
    if (!g.post_convolve) return 1;
    return (g.filter.reach_nodes() == 2 ? 2 * L - 1 : L - 1) + L;
}

}  // namespace

SheetGeometry::SheetGeometry(const Camera& camera) {
    const Mat4& w2c = camera.world_to_camera();
    auto depth_of = [&](const Vec3& p) { return -(w2c.m[2][0] * p.x + w2c.m[2][1] * p.y + w2c.m[2][2] * p.z + w2c.m[2][3]); };
    auto rate_of = [&](const Vec3& d) { return -(w2c.m[2][0] * d.x + w2c.m[2][1] * d.y + w2c.m[2][2] * d.z); };
    auto at = [&](double px, double py, Vec3& origin, Vec3& dir) {
        const Ray r = camera.pixel_ray(px, py);
        dir = r.direction / rate_of(r.direction);
        origin = r.origin - dir * depth_of(r.origin);
    };
    Vec3 o1, d1, o2, d2;
    at(0, 0, origin0, dir0);
    at(1, 0, o1, d1);
    at(0, 1, o2, d2);
    origin_dx = o1 - origin0;
    origin_dy = o2 - origin0;
    dir_dx = d1 - dir0;
    dir_dy = d2 - dir0;
}

void WalkStats::add(const WalkStats& o) {
    voxels_splatted += o.voxels_splatted;
    voxels_occluded += o.voxels_occluded;
    tiles_terminated += o.tiles_terminated;
    tile_sheets_composited += o.tile_sheets_composited;
    tile_sheets_skipped += o.tile_sheets_skipped;
    seconds_splat += o.seconds_splat;
    seconds_post_convolution += o.seconds_post_convolution;
    seconds_shading += o.seconds_shading;
    first_sheet = std::min(first_sheet, o.first_sheet);
    last_sheet = std::max(last_sheet, o.last_sheet);
}

/// One grid's part of a tile: its ring, its post-convolved sheets s - 1, s, s + 1 and its occlusion map.
struct SheetWalker::GridState {
    bool used = false;
    SheetRing ring;
    RingPlacement placement;
    OcclusionMap occlusion;
    int halo = 1;
    int x0 = 0, y0 = 0, width = 0, height = 0;  // post-convolved region: the tile and its halo
    std::vector<float> slots[3];                // post-convolved sheet s in slot s mod 3
    bool content[3] = {false, false, false};
    std::vector<float> zeros;

    size_t pitch() const { return size_t(width); }
    const float* sheet(int64_t s) const {
        const int k = int(((s % 3) + 3) % 3);
        return content[k] ? slots[k].data() : zeros.data();
    }
    bool has(int64_t s) const { return content[((s % 3) + 3) % 3]; }
};

SheetWalker::SheetWalker() = default;
SheetWalker::~SheetWalker() = default;

void SheetWalker::render(const SheetWalkSetup& setup, size_t tile, float* image, WalkStats& stats, RenderControl& control) {
    const TileSet& tiles = *setup.tiles;
    const std::vector<TileBlock>& blocks = tiles.blocks(tile);
    if (blocks.empty()) return;
    const PixelRect rect = tiles.rect(tile);
    const int tw = rect.width(), th = rect.height();
    const bool mip = setup.shader == nullptr;
    const SheetLattice& sheets = setup.sheets;
    const float cutoff = setup.opacity_cutoff;
    const bool occlusion_culling = !mip && cutoff < 1.0f;

    // Each grid listed in the tile gets a ring over the nodes its post-convolution reads.
    if (grids_.size() < setup.grids.size()) grids_.resize(setup.grids.size());
    double deepest_reach = 0;
    int ring_depth = 0;
    for (auto& g : grids_)
        if (g) g->used = false;
    for (const TileBlock& b : blocks) {
        auto& state = grids_[b.grid];
        if (!state) state = std::make_unique<GridState>();
        if (state->used) continue;
        const WalkGrid& wg = setup.grids[b.grid];
        GridState& g = *state;
        g.used = true;
        const int L = wg.view->stride();
        g.halo = gradient_halo(wg);
        g.x0 = rect.x0 - g.halo;
        g.y0 = rect.y0 - g.halo;
        g.width = tw + 2 * g.halo;
        g.height = th + 2 * g.halo;
        int nx0, ny0, nx1, ny1;
        if (wg.post_convolve) {
            nx0 = floor_div(g.x0, L) - 1, nx1 = floor_div(g.x0 + g.width - 1, L) + 2;
            ny0 = floor_div(g.y0, L) - 1, ny1 = floor_div(g.y0 + g.height - 1, L) + 2;
        } else {
            nx0 = g.x0, nx1 = g.x0 + g.width - 1, ny0 = g.y0, ny1 = g.y0 + g.height - 1;
        }
        g.placement = {nx0, ny0};
        const double reach = wg.view->depth_reach();
        deepest_reach = std::max(deepest_reach, reach);
        // Sheets alive: from s (the walk's first) or s + 1 to the last one a voxel splatted for sheet s
        // reaches, s + 2 + 2 reach / spacing; two more for rounding.
        const int depth = int(std::ceil(2.0 * reach / sheets.spacing)) + 6;
        ring_depth = std::max(ring_depth, depth);
        g.ring.reset(nx1 - nx0 + 1, ny1 - ny0 + 1, depth);
        for (auto& slot : g.slots) slot.resize(size_t(g.width) * g.height);
        g.zeros.assign(size_t(g.width) * g.height, 0.0f);
        std::fill(std::begin(g.content), std::end(g.content), false);
        g.occlusion.disable();
    }

    const size_t tile_pixels = size_t(tw) * th;
    accumulated_.assign(tile_pixels, Rgba{});
    if (mip) maximum_.assign(tile_pixels, -INFINITY);
    size_t opaque = 0, opaque_at_rebuild = 0;
    const size_t rebuild_step = std::max<size_t>(1, tile_pixels / 16);

    struct Active {
        size_t entry;  // into blocks
        int next_rank;
    };
    std::vector<Active> active;
    size_t next_entry = 0;
    // Blocks are sorted by the depth where their kernels begin: the first one starts the walk, one
    // sheet early, since samples between that sheet and the one before it see it too.
    int64_t s = std::max<int64_t>(0, sheets.slab_of(blocks.front().front) - 1);
    int64_t open_sheet = s;  // the first sheet not yet post-convolved: deposits before it are dropped

    int64_t sheets_walked = 0;
    bool terminated = false;
    while (s < sheets.count) {
        if ((++sheets_walked & 15) == 0) control.throw_if_cancelled();

        // 1. Splat every voxel that reaches sheet s + 1: centre depth - reach < boundary(s + 2).
        auto t0 = Clock::now();
        const double splat_front = sheets.boundary(s + 2);
        while (next_entry < blocks.size() && blocks[next_entry].front < splat_front) active.push_back({next_entry++, 0});
        // In activation order, so that every node sums its contributions in the same order whichever
        // other blocks the tile lists (culled or not).
        size_t kept = 0;
        for (size_t a = 0; a < active.size(); ++a) {
            const TileBlock& tb = blocks[active[a].entry];
            const WalkGrid& wg = setup.grids[tb.grid];
            GridState& g = *grids_[tb.grid];
            const SlabView& view = *wg.view;
            const VoxelBlock& block = view.grid().blocks()[tb.block];
            const float limit = float(splat_front + view.depth_reach() - view.origin_depth(block));
            const std::vector<float>& depth = view.depth_order().depth;
            int last = active[a].next_rank;
            while (last < VoxelBlock::kSize && depth[last] < limit) ++last;
            const DepositCounts n = view.deposit(block, active[a].next_rank, last, g.ring, g.placement, open_sheet,
                                                 occlusion_culling && g.occlusion.active() ? &g.occlusion : nullptr);
            stats.voxels_splatted += n.splatted;
            stats.voxels_occluded += n.occluded;
            active[a].next_rank = last;
            if (last < VoxelBlock::kSize) active[kept++] = active[a];
        }
        active.resize(kept);
        auto t1 = Clock::now();
        stats.seconds_splat += std::chrono::duration<double>(t1 - t0).count();

        // 2. Post-convolve sheet s + 1 of every grid (after a start or a jump, s too).
        for (size_t gi = 0; gi < grids_.size(); ++gi) {
            if (!grids_[gi] || !grids_[gi]->used) continue;
            GridState& g = *grids_[gi];
            const WalkGrid& wg = setup.grids[gi];
            for (int64_t t = open_sheet; t <= s + 1; ++t) {
                const int k = int(((t % 3) + 3) % 3);
                g.content[k] = g.ring.touched(t);
                if (!g.content[k]) continue;
                float* out = g.slots[k].data();
                if (wg.post_convolve) {
                    const NodeSheet nodes{g.ring.sheet(t), g.ring.pitch(), g.placement.node_x0, g.placement.node_y0};
                    post_convolve_region(nodes, wg.filter, g.x0, g.y0, g.width, g.height, out, g.pitch(), scratch_);
                } else {
                    for (int r = 0; r < g.height; ++r)
                        std::memcpy(out + size_t(r) * g.pitch(), g.ring.sheet(t) + size_t(r) * g.ring.pitch(), sizeof(float) * g.width);
                }
                g.ring.release(t);
            }
        }
        open_sheet = s + 2;
        auto t2 = Clock::now();
        stats.seconds_post_convolution += std::chrono::duration<double>(t2 - t1).count();

        // 3. Classify, shade and composite from sheet s towards s + 1 (MIP: take the maximum at s).
        bool any = false;
        for (const auto& g : grids_) any |= g && g->used && (g->has(s) || (!mip && g->has(s + 1)));
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
            for (size_t gi = 0; gi < grids_.size(); ++gi) {
                if (!grids_[gi] || !grids_[gi]->used) continue;
                GridState& g = *grids_[gi];
                const WalkGrid& wg = setup.grids[gi];
                const int L = wg.post_convolve ? wg.view->stride() : 1;
                auto is_opaque = [&](int x, int y) { return accumulated_[size_t(y) * tw + x].a >= cutoff; };
                g.occlusion.rebuild(tw, th, is_opaque, L, rect.x0 - L * g.placement.node_x0, rect.y0 - L * g.placement.node_y0,
                                    g.ring.columns(), g.ring.rows(), node_reach(wg));
            }
        }

        // 5. Nothing left in the rings and nothing splatting: jump to the next block's first sheet.
        bool pending = !active.empty();
        for (const auto& g : grids_) {
            if (!g || !g->used) continue;
            pending |= g->has(s + 1);
            for (int k = 2; k < ring_depth && !pending; ++k) pending |= g->ring.touched(s + k);
        }
        if (!pending) {
            if (next_entry == blocks.size()) break;
            const int64_t next = sheets.slab_of(blocks[next_entry].front) - 1;
            if (next > s + 1) {
                stats.tile_sheets_skipped += uint64_t(next - s - 1);
                for (const auto& g : grids_)
                    if (g) std::fill(std::begin(g->content), std::end(g->content), false);
                s = open_sheet = next;
                continue;
            }
        }
        ++s;
    }
    if (terminated) ++stats.tiles_terminated;

    // The tile into the image.
    for (int y = 0; y < th; ++y) {
        const size_t row = size_t(rect.y0 + y) * setup.width + rect.x0;
        for (int x = 0; x < tw; ++x) {
            const size_t p = size_t(y) * tw + x;
            if (mip) {
                image[row + x] = std::isfinite(maximum_[p]) ? maximum_[p] : 0.0f;
            } else {
                const Rgba& c = accumulated_[p];
                float* out = image + 4 * (row + x);
                out[0] = c.r, out[1] = c.g, out[2] = c.b, out[3] = c.a;
            }
        }
    }
}

void SheetWalker::take_maximum(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s) {
    const int tw = rect.width(), th = rect.height();
    for (size_t gi = 0; gi < grids_.size(); ++gi) {
        if (!grids_[gi] || !grids_[gi]->used || !grids_[gi]->has(s)) continue;
        const GridState& g = *grids_[gi];
        const float *before = g.sheet(s - 1), *here = g.sheet(s), *after = g.sheet(s + 1);
        for (int y = 0; y < th; ++y)
            for (int x = 0; x < tw; ++x) {
                const size_t i = size_t(y + g.halo) * g.pitch() + size_t(x + g.halo);
                const float m = here[i];
                if (m == 0.0f) continue;  // no voxel reaches: empty
                // A slab mean is lower than the peak inside it: at a local maximum along the ray, the
                // parabola through the three slab means locates the peak, and a parabola's slab mean
                // lies its curvature / 24 below its value (the box filter's second moment).
                float peak = m;
                const float curvature = 2.0f * m - before[i] - after[i];
                if (m >= before[i] && m >= after[i] && curvature > 0) {
                    const float slope = after[i] - before[i];
                    peak += slope * slope / (8.0f * curvature) + curvature / 24.0f;
                }
                const Vec3 dir = setup.geometry->direction(rect.x0 + x, rect.y0 + y);
                float& most = maximum_[size_t(y) * tw + x];
                most = std::max(most, peak / float(setup.sheets.spacing * length(dir)));
            }
    }
}

size_t SheetWalker::composite_sample(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s, float t, int samples) {
    const SheetGeometry& geo = *setup.geometry;
    const float spacing = float(setup.sheets.spacing), cutoff = setup.opacity_cutoff;
    const int tw = rect.width(), th = rect.height();
    // The sample lies t of the way from sheet s's middle to sheet s + 1's, and stands for 1 / samples of a slab.
    const double depth = setup.sheets.boundary(s) + (0.5 + double(t)) * setup.sheets.spacing;
    const Vec3f a = to_float(geo.origin_dx + geo.dir_dx * depth), b = to_float(geo.origin_dy + geo.dir_dy * depth);
    const Vec3f a_cross_b = cross3(a, b);
    const Vec3f origin_dx = to_float(geo.origin_dx), origin_dy = to_float(geo.origin_dy), origin0 = to_float(geo.origin0);
    size_t newly_opaque = 0;
    for (int y = 0; y < th; ++y) {
        const int py = rect.y0 + y;
        for (int x = 0; x < tw; ++x) {
            Rgba& acc = accumulated_[size_t(y) * tw + x];
            if (acc.a >= cutoff) continue;
            const int px = rect.x0 + x;
            const Vec3f dir = to_float(geo.direction(px, py));
            const float dir_length = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
            const float slab_length = spacing * dir_length;  // world length of the ray across a slab
            float sigma_sum = 0;
            Vec3f emission{0, 0, 0};
            for (size_t gi = 0; gi < grids_.size(); ++gi) {
                if (!grids_[gi] || !grids_[gi]->used) continue;
                const GridState& g = *grids_[gi];
                if (!g.has(s) && !(t > 0 && g.has(s + 1))) continue;
                const size_t i = size_t(y + g.halo) * g.pitch() + size_t(x + g.halo);
                const float* here = g.sheet(s);
                const float* next = g.sheet(s + 1);
                const float raw = here[i] + t * (next[i] - here[i]);
                if (raw == 0.0f) continue;  // no voxel reaches: empty
                const ClassificationTable::Sample c = (*setup.grids[gi].classification)(raw / slab_length);
                if (!(c.extinction > 0)) continue;
                // Density change per pixel right, per pixel down and per unit of depth along the ray, of
                // the density interpolated linearly between the sheets (common factors dropped: only the
                // gradient's direction matters). On a sheet the depth slope is the central difference.
                const int L = g.halo;
                const size_t pitch = g.pitch();
                auto across = [&](const float* sheet, size_t step) { return sheet[i + step] - sheet[i - step]; };
                const float g1 = (across(here, L) + t * (across(next, L) - across(here, L))) / float(2 * L);
                const float g2 = (across(here, L * pitch) + t * (across(next, L * pitch) - across(here, L * pitch))) / float(2 * L);
                const float g3 = t == 0 ? (next[i] - g.sheet(s - 1)[i]) / (2.0f * spacing) : (next[i] - here[i]) / spacing;
                // World gradient from the derivatives along the pixel axes and the ray: the rows of the
                // inverse of [a b dir] are (b x dir, dir x a, a x b) / det.
                const Vec3f gradient = cross3(b, dir) * g1 + cross3(dir, a) * g2 + a_cross_b * g3;
                const Vec3f to_eye = dir * (-1.0f / dir_length);
                const Vec3f position = origin0 + origin_dx * float(px) + origin_dy * float(py) + dir * float(depth);
                const Vec3f lit = setup.shader->shade({c.red, c.green, c.blue}, gradient, to_eye, position);
                sigma_sum += c.extinction;
                emission = emission + lit * c.extinction;
            }
            if (sigma_sum > 0) {
                // Overlapping grids mix as media do: extinctions add, emissions weigh by extinction.
                const float alpha = slab_opacity(sigma_sum, slab_length / float(samples)), inv = 1.0f / sigma_sum;
                composite_behind(acc, emission.x * inv, emission.y * inv, emission.z * inv, alpha);
                newly_opaque += acc.a >= cutoff;
            }
        }
    }
    return newly_opaque;
}

}  // namespace pcvr
