#include "splat/cut_splat.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "volume/block_voxels.h"

namespace pcvr {

CutProfile::CutProfile(const Kernel& kernel)
    : kernel_(kernel), radius_(kernel.radius()), separable_(kernel.shape() == KernelShape::Gauss14 || kernel.shape() == KernelShape::Gauss20) {
    if (!separable_) return;
    const double r2 = radius_ * radius_;
    rho2_scale_ = kEntries / r2;
    s_scale_ = kEntries / (2.0 * radius_);
    for (int k = 0; k <= kEntries + 1; ++k) {
        centre_.push_back(kernel.value(std::sqrt(std::min(k / rho2_scale_, r2))));
        const double at = std::min(k / s_scale_, 2.0 * radius_) - radius_;  // G is odd
        along_.push_back(std::copysign(kernel.segment_integral(0.0, 0.0, std::abs(at)), at) / kernel.value(0.0));
    }
    centre8_.assign(centre_.begin(), centre_.end());
    along8_.assign(along_.begin(), along_.end());
}

VoxelBlock split_cut_block(const VoxelBlock& block, const ClipRegion& clip, double radius, double density_scale,
                           std::vector<CutVoxel>& cut) {
    VoxelBlock kept = block;
    for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
        if (!block.active(offset)) continue;
        const Vec3 c = voxel_position(block, offset);
        const ClipSide side = clip.sphere_side(c, radius);
        if (side == ClipSide::Inside) continue;
        kept.mask[offset >> 6] &= ~(uint64_t(1) << (offset & 63));
        const double value = double(block.value(offset)) * density_scale;
        if (side == ClipSide::Straddles && value != 0.0 && std::isfinite(value)) cut.push_back({c, value});
    }
    return kept;
}

namespace {

using Quadratic2 = CutSplatter::Quadratic2;
using Linear2 = CutSplatter::Linear2;

/// The pixels whose rays can meet a kernel: the projection of its bounding cube, or the whole image
/// when part of the cube lies behind the eye.
struct PixelSpan {
    int x0, y0, x1, y1;
};

PixelSpan kernel_pixels(const Vec3& c, double radius, const ViewProjection& view) {
    const Camera& cam = view.camera();
    PixelSpan all{0, 0, cam.width() - 1, cam.height() - 1};
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (int k = 0; k < 8; ++k) {
        const Vec4 p = view.to_clip({c.x + ((k & 1) ? radius : -radius), c.y + ((k & 2) ? radius : -radius),
                                     c.z + ((k & 4) ? radius : -radius)});
        if (!(p.w > 0)) return all;
        const double px = cam.pixel_x(p.x / p.w), py = cam.pixel_y(p.y / p.w);
        x0 = std::min(x0, px), x1 = std::max(x1, px), y0 = std::min(y0, py), y1 = std::max(y1, py);
    }
    return {clamp_to_int(std::ceil(x0), 0, cam.width()), clamp_to_int(std::ceil(y0), 0, cam.height()),
            clamp_to_int(std::floor(x1), -1, cam.width() - 1), clamp_to_int(std::floor(y1), -1, cam.height() - 1)};
}

/// (a0 + x ax + y ay) . (b0 + x bx + y by) as a quadratic in (x, y).
Quadratic2 product(const Vec3& a0, const Vec3& ax, const Vec3& ay, const Vec3& b0, const Vec3& bx, const Vec3& by) {
    return {dot(a0, b0), dot(a0, bx) + dot(ax, b0), dot(a0, by) + dot(ay, b0), dot(ax, bx), dot(ax, by) + dot(ay, bx), dot(ay, by)};
}

struct Quadratic {
    double c0, c1, c2;
    double at(double x) const { return c0 + x * (c1 + x * c2); }
};
struct Linear {
    double c0, c1;
    double at(double x) const { return c0 + x * c1; }
};
Quadratic on_row(const Quadratic2& q, double y) { return {q.c00 + y * (q.c01 + y * q.c02), q.c10 + y * q.c11, q.c20}; }
Linear on_row(const Linear2& l, double y) { return {l.c0 + y * l.cy, l.cx}; }

}  // namespace

/// One row of a voxel's cut footprint (the double path, add_rows): w.D, D.D, w.w and W.W as quadratics in
/// the column x (w = centre - o(x)), and for the planes that pass within the kernel's radius (the others
/// leave its chord whole) n.o + d and n.D, linear in x. The vectors keep their memory from row to row.
struct CutScratch::Row {
    Quadratic wd, dd, ww, world;
    std::vector<Linear> value, rate;

    /// The kept interval [lo, hi] of the ray's parameter t at column x; empty when lo >= hi.
    void kept(double x, double& lo, double& hi) const {
        lo = -1e300, hi = 1e300;
        for (size_t k = 0; k < value.size(); ++k) {
            const double v = value[k].at(x), r = rate[k].at(x);
            if (r > 0)
                lo = std::max(lo, -v / r);
            else if (r < 0)
                hi = std::min(hi, -v / r);
            else if (v < 0)
                hi = -1e300;
        }
    }
};

CutScratch::CutScratch() : row(std::make_unique<Row>()) {}
CutScratch::~CutScratch() = default;

CutSplatter::CutSplatter(const ViewProjection& view, const ClipRegion& clip, const Kernel& kernel)
    : view_(view), clip_(clip), profile_(kernel) {
    const Ray r0 = view.index_ray(0, 0), rx = view.index_ray(1, 0), ry = view.index_ray(0, 1);
    o0_ = r0.origin, ox_ = rx.origin - r0.origin, oy_ = ry.origin - r0.origin;
    d0_ = r0.direction, dx_ = rx.direction - r0.direction, dy_ = ry.direction - r0.direction;
    parallel_ = view.orthographic();
    if (parallel_) dx_ = dy_ = {0, 0, 0};
    const Vec3 w0 = view.world_direction(0, 0), wx = view.world_direction(1, 0) - w0, wy = view.world_direction(0, 1) - w0;
    dd_ = product(d0_, dx_, dy_, d0_, dx_, dy_);
    world_ = parallel_ ? Quadratic2{dot(w0, w0)} : product(w0, wx, wy, w0, wx, wy);
    if (parallel_) {  // pixel coordinates are affine in index space; a sphere's shadow reaches R |gradient|
        const Camera& cam = view.camera();
        auto pixel = [&](const Vec3& p) {
            const Vec4 c = view.to_clip(p);
            return std::pair<double, double>{cam.pixel_x(c.x / c.w), cam.pixel_y(c.y / c.w)};
        };
        const auto [x0, y0] = pixel({0, 0, 0});
        const auto [xi, yi] = pixel({1, 0, 0});
        const auto [xj, yj] = pixel({0, 1, 0});
        const auto [xk, yk] = pixel({0, 0, 1});
        pixel_x0_ = x0, pixel_y0_ = y0;
        pixel_x_ = {xi - x0, xj - x0, xk - x0}, pixel_y_ = {yi - y0, yj - y0, yk - y0};
        reach_x_ = kernel.radius() * length(pixel_x_), reach_y_ = kernel.radius() * length(pixel_y_);
    }
    for (const ClipPlane& p : clip.planes()) {
        plane_value_.push_back({p.at(o0_), dot(p.normal, ox_), dot(p.normal, oy_)});
        plane_rate_.push_back({dot(p.normal, d0_), dot(p.normal, dx_), dot(p.normal, dy_)});
        // Index-space normals are unit: within 1e-6 radians of the rays, which takes in planes from single-
        // precision matrices (Blender's: a quarter turn leaves cos = 4e-8); a kernel's kept share would move
        // by at most 4e-6 voxels across its footprint, below what float resolves of a footprint.
        edge_on_.push_back(parallel_ && std::abs(dot(p.normal, d0_)) <= 1e-6 * length(d0_));
    }
}

bool CutSplatter::smooth(const CutVoxel& voxel) const {
    const Vec3 towards = view_.orthographic() ? d0_ : voxel.centre - view_.eye();
    const double along = length(towards);
    for (size_t k = 0; k < clip_.planes().size(); ++k) {
        const ClipPlane& p = clip_.planes()[k];
        if (!edge_on_[k] && std::abs(p.at(voxel.centre)) < profile_.radius() && std::abs(dot(p.normal, towards)) < kSmoothCut * along)
            return false;
    }
    return true;
}

ClipRegion CutSplatter::unmasked() const {
    std::vector<ClipPlane> planes;
    for (size_t k = 0; k < edge_on_.size(); ++k)
        if (!edge_on_[k]) planes.push_back(clip_.planes()[k]);
    return ClipRegion::from(planes);
}

bool CutSplatter::masks() const { return std::find(edge_on_.begin(), edge_on_.end(), char(1)) != edge_on_.end(); }

void CutSplatter::mask(ImageAccumulator& image) const {
    for (size_t k = 0; k < edge_on_.size(); ++k) {
        if (!edge_on_[k]) continue;
        const Linear2& value = plane_value_[k];  // the same all along each ray
        for (int y = 0; y < image.height; ++y) {
            float* row = image.pixels.data() + size_t(y) * image.width;
            for (int x = 0; x < image.width; ++x)
                if (value.c0 + value.cx * x + value.cy * y < 0) row[x] = 0.0f;
        }
    }
}

template <class RowOf>
uint64_t CutSplatter::add(const CutVoxel& v, const Lattice& at, CutScratch& scratch, RowOf&& out) const {
    if (!ViewProjection::inside_clip_range(view_.to_clip(v.centre))) return 0;
    return profile_.separable() ? add_lanes(v, at, scratch, out) : add_rows(v, at, scratch, out);
}

template <class RowOf>
uint64_t CutSplatter::add_rows(const CutVoxel& v, const Lattice& at, CutScratch& scratch, RowOf&& out) const {
    const double radius = profile_.radius(), radius2 = radius * radius;
    const PixelSpan span = kernel_pixels(v.centre, radius, view_);
    const int c0 = clamp_to_int(std::ceil(span.x0 / at.scale) - at.first_column, 0, at.columns);
    const int c1 = clamp_to_int(std::floor(span.x1 / at.scale) - at.first_column, -1, at.columns - 1);
    const int r0 = clamp_to_int(std::ceil(span.y0 / at.scale) - at.first_row, 0, at.rows);
    const int r1 = clamp_to_int(std::floor(span.y1 / at.scale) - at.first_row, -1, at.rows - 1);
    // w = centre - o(x, y): w.D and w.w over the image, and the planes near this kernel.
    const Vec3 w0 = v.centre - o0_;
    const Quadratic2 wd = product(w0, -ox_, -oy_, d0_, dx_, dy_), ww = product(w0, -ox_, -oy_, w0, -ox_, -oy_);
    std::vector<size_t>& near = scratch.near;
    near.clear();
    for (size_t k = 0; k < clip_.planes().size(); ++k)
        if (!edge_on_[k] && std::abs(clip_.planes()[k].at(v.centre)) < radius) near.push_back(k);
    CutScratch::Row& row = *scratch.row;
    uint64_t taps = 0;
    for (int r = r0; r <= r1; ++r) {
        const double y = at.scale * (r + at.first_row);
        row.wd = on_row(wd, y), row.dd = on_row(dd_, y), row.ww = on_row(ww, y), row.world = on_row(world_, y);
        row.value.clear(), row.rate.clear();
        for (size_t k : near) row.value.push_back(on_row(plane_value_[k], y)), row.rate.push_back(on_row(plane_rate_[k], y));
        auto* values = out(r);
        for (int c = c0; c <= c1; ++c) {
            const double x = at.scale * (c + at.first_column);
            const double dd = row.dd.at(x), wd_x = row.wd.at(x), inverse = 1.0 / dd;
            const double rho2 = row.ww.at(x) - wd_x * wd_x * inverse;
            if (!(rho2 < radius2)) continue;
            ++taps;
            // The kept interval of t (the ray's parameter) and where t passes the centre.
            double lo, hi;
            row.kept(x, lo, hi);
            if (!(lo < hi)) continue;
            // In index units along the ray from its closest approach, and world length per index length.
            const double closest = wd_x * inverse, index_length = std::sqrt(dd);
            values[c] += v.amplitude * std::sqrt(row.world.at(x) * inverse) *
                         profile_(std::max(rho2, 0.0), (lo - closest) * index_length, (hi - closest) * index_length);
        }
    }
    return taps;
}

namespace {

/// A polynomial of degree two in the lattice offsets (u, v) of a kernel's first lattice point, in float:
/// set up in double where its terms are large, evaluated where its values are small.
struct Poly2 {
    float c, u, v, uu, uv, vv;
    /// Its restriction to row v: c0 + c1 u + c2 u^2.
    void row(float fv, float& c0, float& c1, float& c2) const { c0 = c + fv * (v + fv * vv), c1 = u + fv * uv, c2 = uu; }
};

/// (a + u au + v av) . (b + u bu + v bv).
Poly2 dot2(const Vec3& a, const Vec3& au, const Vec3& av, const Vec3& b, const Vec3& bu, const Vec3& bv) {
    return {float(dot(a, b)),           float(dot(au, b) + dot(a, bu)), float(dot(av, b) + dot(a, bv)),
            float(dot(au, bu)),         float(dot(au, bv) + dot(av, bu)), float(dot(av, bv))};
}

/// One component (`axis`) of (a + u au + v av) x (b + u bu + v bv).
Poly2 cross2(const Vec3& a, const Vec3& au, const Vec3& av, const Vec3& b, const Vec3& bu, const Vec3& bv, int axis) {
    auto part = [axis](const Vec3& p, const Vec3& q) { return cross(p, q)[axis]; };
    return {float(part(a, b)),   float(part(au, b) + part(a, bu)), float(part(av, b) + part(a, bv)),
            float(part(au, bu)), float(part(au, bv) + part(av, bu)), float(part(av, bv))};
}

}  // namespace

template <class RowOf>
uint64_t CutSplatter::add_lanes(const CutVoxel& v, const Lattice& at, CutScratch& scratch, RowOf&& out) const {
    const double radius = profile_.radius(), step = at.scale;
    int c0, c1, r0, r1;
    if (parallel_) {  // around the projected centre, R times each pixel axis' gradient
        const double cx = pixel_x0_ + dot(pixel_x_, v.centre), cy = pixel_y0_ + dot(pixel_y_, v.centre);
        c0 = clamp_to_int(std::ceil((cx - reach_x_) / step) - at.first_column, 0, at.columns);
        c1 = clamp_to_int(std::floor((cx + reach_x_) / step) - at.first_column, -1, at.columns - 1);
        r0 = clamp_to_int(std::ceil((cy - reach_y_) / step) - at.first_row, 0, at.rows);
        r1 = clamp_to_int(std::floor((cy + reach_y_) / step) - at.first_row, -1, at.rows - 1);
    } else {
        const PixelSpan span = kernel_pixels(v.centre, radius, view_);
        c0 = clamp_to_int(std::ceil(span.x0 / step) - at.first_column, 0, at.columns);
        c1 = clamp_to_int(std::floor(span.x1 / step) - at.first_column, -1, at.columns - 1);
        r0 = clamp_to_int(std::ceil(span.y0 / step) - at.first_row, 0, at.rows);
        r1 = clamp_to_int(std::floor(span.y1 / step) - at.first_row, -1, at.rows - 1);
    }
    if (c0 > c1 || r0 > r1) return 0;
    // The ray through lattice point (c0 + u, r0 + v): origin o + u o_u + v o_v, direction D + u D_u + v D_v
    // (t along D), and w = centre - origin. rho^2 = |w x D|^2 / D.D, the closest approach t = w.D / D.D.
    const double x0 = step * (c0 + at.first_column), y0 = step * (r0 + at.first_row);
    const Vec3 o = o0_ + ox_ * x0 + oy_ * y0, d = d0_ + dx_ * x0 + dy_ * y0;
    const Vec3 ou = ox_ * step, ov = oy_ * step, du = dx_ * step, dv = dy_ * step;
    const Vec3 w = v.centre - o, wu = -ou, wv = -ov;
    const Poly2 cx = cross2(w, wu, wv, d, du, dv, 0), cy = cross2(w, wu, wv, d, du, dv, 1), cz = cross2(w, wu, wv, d, du, dv, 2);
    const Poly2 wd = dot2(w, wu, wv, d, du, dv), dd = dot2(d, du, dv, d, du, dv);
    const Vec3 world = view_.world_direction(x0, y0), world_u = (view_.world_direction(x0 + 1, y0) - world) * step,
               world_v = (view_.world_direction(x0, y0 + 1) - world) * step;
    const Poly2 ww = dot2(world, world_u, world_v, world, world_u, world_v);
    // The planes near the kernel: n.origin + offset and n.D, linear in (u, v).
    struct Plane {
        float value, value_u, value_v, rate, rate_u, rate_v;
    };
    Plane planes[8];
    int n_planes = 0;
    for (size_t k = 0; k < clip_.planes().size(); ++k) {
        const ClipPlane& p = clip_.planes()[k];
        if (edge_on_[k] || !(std::abs(p.at(v.centre)) < radius)) continue;
        if (n_planes == 8) return add_rows(v, at, scratch, out);  // more than the lanes take
        planes[n_planes++] = {float(p.at(o)), float(dot(p.normal, ou)), float(dot(p.normal, ov)),
                              float(dot(p.normal, d)), float(dot(p.normal, du)), float(dot(p.normal, dv))};
    }
    const float r2 = float(radius * radius), amplitude = float(v.amplitude);
    const int columns = c1 - c0 + 1;
    uint64_t taps = 0;
    for (int row = 0; row <= r1 - r0; ++row) {
        const float fv = float(row);
        float x[3], y[3], z[3], a[3], b[3], ws[3];
        cx.row(fv, x[0], x[1], x[2]), cy.row(fv, y[0], y[1], y[2]), cz.row(fv, z[0], z[1], z[2]);
        wd.row(fv, a[0], a[1], a[2]), dd.row(fv, b[0], b[1], b[2]), ww.row(fv, ws[0], ws[1], ws[2]);
        auto* values = out(r0 + row) + c0;
        for (int u0 = 0; u0 < columns; u0 += 8) {
            const float8 u = broadcast8(float(u0)) + lane_index8();
            auto at_u = [&u](const float (&q)[3]) { return q[0] + u * (q[1] + u * q[2]); };
            const float8 ex = at_u(x), ey = at_u(y), ez = at_u(z), dd_u = at_u(b), inverse = 1.0f / dd_u;
            const float8 rho2 = (ex * ex + ey * ey + ez * ez) * inverse;
            int8x inside = (rho2 < r2) & (u < float(columns));
            if (!any8(inside)) continue;
            taps += uint64_t(__builtin_popcount(lane_mask(inside)));
            // The kept interval of t, from the closest approach, in index units (|D| per unit of t).
            const float8 closest = at_u(a) * inverse, length = sqrt8(dd_u);
            const float8 half = sqrt8(max8(r2 - rho2, broadcast8(0.0f)));
            float8 s0 = -half, s1 = half;
            for (int k = 0; k < n_planes; ++k) {
                const Plane& p = planes[k];
                const float8 value = (p.value + fv * p.value_v) + u * p.value_u, rate = (p.rate + fv * p.rate_v) + u * p.rate_u;
                const float8 end = (-value / rate - closest) * length;
                s0 = select8(rate > 0, max8(s0, end), s0);
                s1 = select8(rate < 0, min8(s1, end), s1);
                inside &= (rate != 0) | (value >= 0);
            }
            s0 = min8(s0, half), s1 = max8(s1, -half);
            inside &= s1 > s0;
            if (!any8(inside)) continue;
            // World length per index length: |W| / |D|.
            const float8 scale = amplitude * sqrt8(max8(at_u(ws), broadcast8(0.0f)) * inverse);
            const float8 kept = select8(inside, scale * profile_(max8(rho2, broadcast8(0.0f)), s0, s1), broadcast8(0.0f));
            for (int j = 0; j < 8; ++j) values[u0 + j] += kept[j];
        }
    }
    return taps;
}

uint64_t CutSplatter::splat(const CutVoxel& voxel, SplatGrid& grid, CutScratch& scratch) const {
    const Lattice nodes{grid.stride(), grid.first_node_x(), grid.first_node_y(), grid.columns(), grid.rows()};
    int r_min = grid.rows(), r_max = -1;
    const uint64_t taps = add(voxel, nodes, scratch, [&](int r) {
        r_min = std::min(r_min, r), r_max = std::max(r_max, r);
        return grid.row(r);
    });
    if (r_min <= r_max) grid.mark(0, r_min, grid.columns() - 1, r_max);
    return taps;
}

uint64_t CutSplatter::splat(const std::vector<CutVoxel>& voxels, ImageAccumulator& image, RenderControl& control) const {
    if (voxels.empty()) return 0;
    const Lattice pixels{1.0, 0, 0, image.width, image.height};
    // Eight more: a row's vector of eight taps may reach past the image's last pixel (adding zeros).
    tbb::enumerable_thread_specific<std::vector<double>> locals([&] { return std::vector<double>(image.pixels.size() + 8, 0.0); });
    tbb::enumerable_thread_specific<uint64_t> taps(0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.size(), 64), [&](const tbb::blocked_range<size_t>& range) {
        control.throw_if_cancelled();
        std::vector<double>& out = locals.local();
        CutScratch scratch;
        for (size_t i = range.begin(); i != range.end(); ++i)
            taps.local() += add(voxels[i], pixels, scratch, [&](int r) { return out.data() + size_t(r) * image.width; });
    });
    control.throw_if_cancelled();
    for (const std::vector<double>& local : locals)
        for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] += float(local[i]);
    uint64_t total = 0;
    for (uint64_t t : taps) total += t;
    return total;
}

}  // namespace pcvr
