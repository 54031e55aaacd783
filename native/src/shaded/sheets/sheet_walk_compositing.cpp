/// @file sheet_walk_compositing.cpp
/// @brief The walk's samples between two sheets: classified, shaded and composited front to back into the tile
/// (composite_sample, with the Catmull-Rom cubic along the ray, AlongRay), or MIP's maximum (take_maximum).
///
/// Apart from the walk (sheet_walk.cpp), which decides when a sheet is ready: this is what one sample does to the
/// tile's pixels, the renderer's innermost loop, with the pixel helpers only it uses.
#include "shaded/sheets/sheet_walk.h"

#include <algorithm>
#include <cmath>

#include "shaded/classify/emission.h"
#include "shaded/sheets/sheet_walk_state.h"

namespace pcvr {

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
                const int8x clipped = setup.grids[gi].clip ? counted & setup.grids[gi].clip->inside<float8>(f.position) : counted;
                const int8x kept = setup.owned ? clipped & setup.owned->owns(f.position) : clipped;
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
    // One grid, the common case, without the loops over sources: their arrays (sheets, samples, lit colours)
    // had lived on the stack, and the inner loop stored and reloaded them.
    if (setup.grids.size() == 1)
        return setup.preintegrated ? composite_sample_as<true, 1>(setup, rect, s, t, samples)
                                   : composite_sample_as<false, 1>(setup, rect, s, t, samples);
    return setup.preintegrated ? composite_sample_as<true, kMostSources>(setup, rect, s, t, samples)
                               : composite_sample_as<false, kMostSources>(setup, rect, s, t, samples);
}

template <bool Preintegrated, int MostSources>
size_t SheetWalker::composite_sample_as(const SheetWalkSetup& setup, const PixelRect& rect, int64_t s, float t, int samples) {
    const SheetGeometry& geo = *setup.geometry;
    const float spacing = float(setup.sheets.spacing), cutoff = setup.opacity_cutoff;
    // The sample lies t of the way from sheet s's middle to sheet s + 1's, and stands for 1 / samples of a slab.
    // Pre-integrated, it is the stretch from t to t + 1 / samples, classified from the densities at its two
    // ends and its middle, clipped, placed and lit at its middle.
    constexpr bool preintegrated = Preintegrated;
    const float middle = preintegrated ? t + 0.5f / float(samples) : t;
    const double u = setup.sheets.boundary(s) + (0.5 + double(middle)) * setup.sheets.spacing;

    // The grids with something at this sample, their sheets s - 1, s and s + 1, and the pixels where
    // any of them is not zero.
    struct Source {
        const GridState* grid;
        const ClassificationTable* classification;
        const Shader* shader;
        const SampleClip* clip;
        const PreintegrationTable* preintegration;
        float background;
        const float *before, *here, *after, *beyond;  // sheets s - 1 to s + 2
    };
    // Sheet s alone at t = 0 with one sample per sheet; the cubic reaches s - 1 to s + 2 in between.
    // With several samples, every one of them lies between sheets s and s + 1's values (AlongRay clamps
    // it there): the first (t = 0) marks the vectors where some source may be visible in that range,
    // and the others visit only those, over the same sources and box.
    const bool between = samples > 1 || preintegrated, marking = between && t == 0, marked = between && t > 0;
    const float per_spacing = 1.0f / spacing;
    Source sources[MostSources];
    int source_count = 0;
    Box box;
    for (size_t gi = 0; gi < grids_.size() && source_count < MostSources; ++gi) {
        if (!grids_[gi] || !grids_[gi]->used) continue;
        const GridState& g = *grids_[gi];
        if (!g.reaches(s, between)) continue;
        const WalkGrid& wg = setup.grids[gi];
        sources[source_count++] = {&g,         wg.classification, wg.shader,     wg.clip,        wg.preintegration,
                                   wg.background, g.sheet(s - 1),  g.sheet(s),    g.sheet(s + 1), g.sheet(s + 2)};
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
    int cached_cell_rows[MostSources];
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
    const AlongRay along(middle), front_end(t), back_end(t + 1.0f / float(samples));

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
            float8 sheet_values[MostSources][4], raws[MostSources], backs[MostSources];  // backs: pre-integrated stretches' back ends
            bool any = false;
            for (int k = 0; k < source_count; ++k) {
                const Source& src = sources[k];
                const size_t i = size_t(y + src.grid->halo) * src.grid->pitch() + size_t(x + src.grid->halo);
                const float8 here = load8(src.here + i), after = load8(src.after + i);
                const float8 lo = min8(here, after) * per_spacing + src.background, hi = max8(here, after) * per_spacing + src.background;
                if (!any8(open & ((here != 0) | (after != 0)) & src.classification->maybe_opaque_within(lo, hi))) {
                    raws[k] = backs[k] = broadcast8(0.0f);  // nothing visible: zero, as where no voxel reaches
                    continue;
                }
                if (marking) may_show_[vector] = 1;
                sheet_values[k][0] = load8(src.before + i), sheet_values[k][1] = here, sheet_values[k][2] = after;
                sheet_values[k][3] = load8(src.beyond + i);
                if constexpr (preintegrated) {  // zero is no voxel: a stretch with one such end takes the other's density
                    const float8 f = front_end.value_at(sheet_values[k]), b = back_end.value_at(sheet_values[k]);
                    raws[k] = select8(f != 0, f, b), backs[k] = select8(b != 0, b, f);
                    // The stretch's middle, between its ends' sheets, may cross what its ends do not.
                    any = any || any8(open & (raws[k] != 0) & src.classification->maybe_opaque_within(lo, hi));
                    continue;
                }
                raws[k] = along.value_at(sheet_values[k]);
                any = any || any8(open & (raws[k] != 0) & src.classification->maybe_opaque(raws[k] * per_spacing + src.background));
            }
            if (!any) continue;
            samples_classified_ += uint64_t(__builtin_popcount(lane_mask(open)));
            const SampleFrames f = sample_frames(geo, setup.sheets.spherical, lanes.px, lanes.py, u);
            const float8 share = whole ? broadcast8(1.0f) : setup.clip_share(f.depth, f.depth_rate * float(half_extent));
            open &= share > 0;
            if (setup.owned) open &= setup.owned->owns(f.position);
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
            Vec3x8 lit_colours[MostSources];
            float8 extinctions[MostSources];
            int lit_count = 0;
            for (int k = 0; k < source_count; ++k) {
                const Source& src = sources[k];
                const GridState& g = *src.grid;
                const size_t i = size_t(y + g.halo) * g.pitch() + size_t(x + g.halo);
                const float8(&v)[4] = sheet_values[k];
                const float8 raw = raws[k];
                const float8 front = raw * per_spacing + src.background;
                const float8 back = preintegrated ? backs[k] * per_spacing + src.background : front;
                // Pre-integrated: the reconstruction at the stretch's middle too (its two halves are integrated).
                const float8 middle_raw = preintegrated ? along.value_at(v) : raw;
                const float8 halfway = select8(middle_raw != 0, middle_raw * per_spacing + src.background, 0.5f * (front + back));
                const float8 density = preintegrated ? halfway : front;
                // zero: no voxel reaches
                int8x valid = open & (raw != 0) &
                              (preintegrated ? src.classification->maybe_opaque_within(min8(min8(front, back), halfway),
                                                                                       max8(max8(front, back), halfway))
                                             : src.classification->maybe_opaque(density));
                if (!any8(valid)) continue;
                // The share of the sample's stretch of ray inside the grid's clip region.
                const float8 kept = src.clip ? src.clip->template share<float8>(f.position, f.along * float(half_extent)) : broadcast8(1.0f);
                valid &= kept > 0;
                if (!any8(valid)) continue;
                PreintegrationTable::Slabs slabs;
                if constexpr (preintegrated) slabs = (*src.preintegration)(*src.classification, front, halfway, back, valid);
                const ClassificationTable::Samples c = preintegrated ? slabs.light : (*src.classification)(density);
                if (src.classification->has_emission()) {  // emits whether or not it absorbs
                    const ClassificationTable::Emissions e = preintegrated ? slabs.glow : src.classification->emission(density);
                    glow = glow + Vec3x8{e.red, e.green, e.blue} * select8(valid, kept, broadcast8(0.0f));
                    glowing = true;
                }
                valid &= c.extinction > 0;
                if (!any8(valid)) continue;
                // Density change per pixel right, per pixel down (interpolated linearly between the
                // sheets) and per unit of the sheet parameter (the cubic's slope; on a sheet the central
                // difference); common factors dropped: only the gradient's direction matters.
                // Pre-integrated: at the stretch's middle, where its sample lies (lit at its extinction's centroid
                // it measured the same; at its front the CT phantoms' bone gained 2 dB but the smooth blobs lost 5-8).
                const int L = g.halo;
                const size_t pitch = g.pitch();
                auto across = [&](const float* sheet, size_t step) { return load8(sheet + i + step) - load8(sheet + i - step); };
                const float8 g1 = (across(src.here, L) + middle * (across(src.after, L) - across(src.here, L))) * (0.5f / L);
                const float8 g2 =
                    (across(src.here, L * pitch) + middle * (across(src.after, L * pitch) - across(src.here, L * pitch))) * (0.5f / L);
                const float8 g3 = along.at(v, along.slope) * (1.0f / spacing);
                const Vec3x8 field_gradient = from_x * g1 + from_y * g2 + from_u * g3;
                const bool gradient_opacity = src.classification->has_gradient_opacity();
                const float8 magnitude = gradient_opacity || src.clip
                                             ? gradient_magnitude(field_gradient, ppx, from_x, per_length, spacing)
                                             : broadcast8(0.0f);
                float8 extinction = c.extinction;
                if (gradient_opacity) {
                    extinction = preintegrated ? src.classification->extinction_of(c.extinction, magnitude)
                                               : src.classification->extinction(density, magnitude);
                    valid &= extinction > 0;
                    if (!any8(valid)) continue;
                }
                // A cut face is lit by the plane's normal (sample_clip.h); gradient opacity read the field's.
                const Vec3x8 gradient =
                    src.clip ? src.clip->template face_gradient<float8>(f.position, field_gradient,
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
