#include "shaded/sheets/sheet_sampling.h"

#include <algorithm>
#include <cmath>

namespace pcvr {

float lattice_blur(const Kernel& kernel) {
    if (!kernel.smooth_footprint() || kernel.shape() == KernelShape::Linear) return -1.0f;
    // Three quarters of the blur that matches the kernel's variance: measured closest to the ray caster
    // on the CT head (bone and soft tissue, 512^2 and 1024^2; gauss1.4: w = 0.069, where the full match
    // 0.092 lost 0.3-0.7 dB and w = 0.05 lost 0.4-0.8 dB).
    return float(0.75 * (kernel.variance() - 1.0 / 6.0) / 2.0);
}

SheetSampler::SheetSampler(const PrefilteredLattice& l, const Mat4& index_to_world, const SheetGeometry& geometry, float scale, double span,
                           const ClassificationTable* table, float background_density, int step, PostFilterShape post_shape)
    : lattice(&l), density_scale(scale), block_span(span), classification(table), background(background_density), gradient_step(step) {
    for (int stride = 1; stride <= kMostStride; ++stride) post_filters_.emplace_back(post_shape, stride);
    const Mat4 to_index = *index_to_world.inverse();  // Grid checks its transform is invertible
    const Vec3 o = to_index.transform_point(geometry.origin0);
    origin = {o.x - l.origin[0], o.y - l.origin[1], o.z - l.origin[2]};
    this->to_index = to_index;
    origin_dx = to_index.transform_vector(geometry.origin_dx), origin_dy = to_index.transform_vector(geometry.origin_dy);
    dir0 = to_index.transform_vector(geometry.dir0), dir_dx = to_index.transform_vector(geometry.dir_dx);
    dir_dy = to_index.transform_vector(geometry.dir_dy);
    if (!classification) return;
    // Half a level wider: float's rounding of the decoding cannot narrow them. 0 is what a skipped value holds.
    // Which bricks may show depends on the classification only through its visible span: kept per span with the lattice.
    const auto [visible_from, visible_to] = classification->visible_span();
    auto bits_of = [&](const std::vector<uint16_t>& ranges, int reach) {
        bool built = false;
        auto bits = l.visibility->get({visible_from, visible_to, scale, background_density, reach}, [&] {
            const size_t bricks = size_t(l.bricks[0]) * size_t(l.bricks[1]) * size_t(l.bricks[2]);
            BrickVisibilityCache::Bits visible(bricks / 32 + 1, 0u);
            const float lowest = float(l.range_lowest), level = float(l.range_step);
            const float8 zero = broadcast8(0.0f);
            for (size_t b = 0; b < bricks; b += 8) {
                int8x levels{};
                for (size_t e = 0; e < 8 && b + e < bricks; ++e) levels[e] = ranges[b + e];
                const float8 lo = min8(lowest + (__builtin_convertvector(levels & 255, float8) - 0.5f) * level, zero) * scale + background_density;
                const float8 hi = max8(lowest + (__builtin_convertvector(levels >> 8, float8) + 0.5f) * level, zero) * scale + background_density;
                // b is a multiple of 8: its eight bits share a word.
                visible[b / 32] |= lane_mask(classification->maybe_opaque_within(lo, hi)) << (b % 32);
            }
            return visible;
        }, built);
        visibility_built |= built;
        return bits;
    };
    visible_bricks_ = bits_of(l.ranges, PrefilteredLattice::kRangeReach);
    tight_visible_bricks_ = bits_of(l.tight_ranges, PrefilteredLattice::kTightRangeReach);
}

namespace {

/// A row's sample positions and ray directions in lattice coordinates, as functions of the pixel
/// column px (what sample_frames gives, without the frames the walk's gradients need):
/// position = base + base_dx px + (ray + ray_dx px) scale(px), and index displacement per unit of the
/// sheet parameter (ray + ray_dx px) rate(px), where spheres divide by |metric direction| and planes
/// meet the ray at a depth affine in px.
struct RowRays {
    Vec3 base, base_dx, ray, ray_dx;
    bool spherical = false;
    double u = 0;
    double a = 0, b = 0, c = 0;  // spheres: |metric direction|^2 = a + b px + c px^2
    double depth0 = 0, depth_dx = 0, rate = 1;  // planes: depth = depth0 + depth_dx px; rate = plane_k

    RowRays(const SheetGeometry& g, const SheetSampler& in_lattice, bool is_spherical, double u_, int y)
        : spherical(is_spherical), u(u_) {
        base = in_lattice.origin + in_lattice.origin_dy * double(y);
        base_dx = in_lattice.origin_dx;
        ray = in_lattice.dir0 + in_lattice.dir_dy * double(y);
        ray_dx = in_lattice.dir_dx;
        if (spherical) {
            const Vec3 m0 = g.metric_dir0 + g.metric_dir_dy * double(y), m1 = g.metric_dir_dx;
            a = dot(m0, m0), b = 2.0 * dot(m0, m1), c = dot(m1, m1);
        } else {
            depth0 = (u - g.plane_u0 - g.plane_uy * double(y)) * g.plane_k;
            depth_dx = -g.plane_ux * g.plane_k;
            rate = g.plane_k;
        }
    }

    /// Positions p and displacements per unit of the sheet parameter `along` of eight pixels.
    void at(float8 px, Vec3x8& p, Vec3x8& along) const {
        float8 scale, per_u;
        if (spherical) {
            per_u = rsqrt8(float(a) + px * (float(b) + px * float(c)));
            scale = per_u * float(u);
        } else {
            scale = float(depth0) + px * float(depth_dx);
            per_u = broadcast8(float(rate));
        }
        const Vec3x8 d{float(ray.x) + px * float(ray_dx.x), float(ray.y) + px * float(ray_dx.y), float(ray.z) + px * float(ray_dx.z)};
        p = Vec3x8{float(base.x) + px * float(base_dx.x), float(base.y) + px * float(base_dx.y), float(base.z) + px * float(base_dx.z)} +
            d * scale;
        along = d * per_u;
    }
};

}  // namespace

Vec3x8 SheetSampler::in_index(const Vec3x8& v) const {
    auto row = [&](int r) { return float(to_index.m[r][0]) * v.x + float(to_index.m[r][1]) * v.y + float(to_index.m[r][2]) * v.z; };
    return Vec3x8{row(0), row(1), row(2)};
}

int SheetSampler::stride_at(const SheetGeometry& geometry, bool spherical, double u, int width, int height) const {
    const SampleFrames f = sample_frames(geometry, spherical, broadcast8(0.5f * float(width)), 0.5f * float(height), u);
    const Vec3x8 right = in_index(f.per_pixel_x), down = in_index(f.per_pixel_y);
    const double per_pixel = sqrt8(max8(dot(right, right), dot(down, down)))[0];
    if (!(per_pixel > 0)) return 1;
    return int(std::clamp(std::floor(1.0 / per_pixel + 1e-6), 1.0, double(kMostStride)));
}

const BrickVisibilityCache::Bits* SheetSampler::skip_bits(const SheetGeometry& geometry, bool spherical, double u, float spacing, int x0,
                                                          int y0, int x1, int y1, int spread) const {
    if (!classification) return nullptr;
    // Every test of whether a sample may be visible reads only the values of the two sheets around it at its
    // pixel (the cubic between them is clamped to their range; pre-integrated stretches' ends and middle too):
    // a value at sheet t is read by samples from sheet t - 2 to t + 1 on its ray, whose tests read sheets t - 2
    // to t + 2, and by the in-sheet gradients of the samples a gradient step away, whose tests read sheets
    // t - 1 to t + 1. Those values are interpolated within 1 / (2 sqrt 3) of a sheet and a lattice cell of
    // their middles: the value's reach, in index units, per axis (the bricks' reach is per axis: a ray
    // across the voxels reaches less far along each axis than along itself).
    // It changes slowly and smoothly across the image: 5% more than at the region's corners covers the
    // pixels between them.
    const float8 px = select8(lane_index8() < 4.0f, broadcast8(float(x0)), broadcast8(float(x1)));
    const float pixels = float(gradient_step + spread);
    float most = 0.0f;
    for (int y : {y0, y1}) {
        const SampleFrames f = sample_frames(geometry, spherical, px, float(y), u);
        const Vec3x8 along = in_index(f.along), right = in_index(f.per_pixel_x), down = in_index(f.per_pixel_y);
        auto reach = [&](float8 a, float8 r, float8 d) { return (2.29f * spacing) * abs8(a) + pixels * max8(abs8(r), abs8(d)) + 1.0f; };
        const float8 widest = max8(max8(reach(along.x, right.x, down.x), reach(along.y, right.y, down.y)), reach(along.z, right.z, down.z));
        for (int l = 0; l < 8; ++l) most = std::max(most, 1.05f * widest[l]);
    }
    if (!(most <= float(PrefilteredLattice::kRangeReach))) return nullptr;
    return most <= float(PrefilteredLattice::kTightRangeReach) ? tight_visible_bricks_.get() : visible_bricks_.get();
}

int SheetSampler::sample_run(const SheetGeometry& geometry, bool spherical, double u, float spacing, int x0, int y, int n,
                             const BrickVisibilityCache::Bits* skip, float* out, int width, int step) const {
    const float* values = lattice->values.data();
    const int32_t si = int32_t(lattice->stride_i()), sj = int32_t(lattice->stride_j());
    // Trilinear cells start at elements 0 .. shape - 2 (the margin's zeros lie beyond every voxel's reach).
    const float last_i = float(lattice->shape[0] - 1), last_j = float(lattice->shape[1] - 1), last_k = float(lattice->shape[2] - 1);
    auto inside = [&](const Vec3x8& p) {
        return (p.x >= 0.0f) & (p.x < last_i) & (p.y >= 0.0f) & (p.y < last_j) & (p.z >= 0.0f) & (p.z < last_k);
    };
    // Trilinear interpolation of the lattice at eight lattice positions (0 outside it).
    auto density = [&](const Vec3x8& p) {
        const int8x in = inside(p);
        // Outside lanes read element 0's cell (in range) and are dropped.
        const float8 ci = select8(in, p.x, broadcast8(0.0f)), cj = select8(in, p.y, broadcast8(0.0f)), ck = select8(in, p.z, broadcast8(0.0f));
        const int8x ii = __builtin_convertvector(ci, int8x), ij = __builtin_convertvector(cj, int8x), ik = __builtin_convertvector(ck, int8x);
        const float8 fi = ci - __builtin_convertvector(ii, float8), fj = cj - __builtin_convertvector(ij, float8),
                     fk = ck - __builtin_convertvector(ik, float8);
        const int8x o = ii * si + ij * sj + ik;
        const float8 v00 = lerp_pairs8(values, o, fk), v01 = lerp_pairs8(values, o + sj, fk);
        const float8 v10 = lerp_pairs8(values, o + si, fk), v11 = lerp_pairs8(values, o + si + sj, fk);
        const float8 v0 = v00 + fj * (v01 - v00), v1 = v10 + fj * (v11 - v10);
        return select8(in, v0 + fi * (v1 - v0), broadcast8(0.0f));
    };
    const RowRays rays(geometry, *this, spherical, u, y);
    // The slab's integral by two-point Gauss-Legendre quadrature along the ray (exact for cubics): one
    // sample at its middle would alias thin structures into dots as they cross the sheets.
    const float offset = spacing * 0.28867513f;  // 1 / (2 sqrt 3) of the slab
    const int32_t bj = lattice->bricks[2], bi = lattice->bricks[1] * bj;
    constexpr float per_brick = 1.0f / PrefilteredLattice::kBrick;
    const float8 zero = broadcast8(0.0f);
    int interpolated = 0;
    for (int q = 0; q < n; ++q) {
        Vec3x8 p, along;
        rays.at(float(x0) + float(step) * (float(8 * q) + lane_index8()), p, along);
        if (skip) {
            // Within its reach, everything lies in the value's brick range; where that range (0 included:
            // what a skipped value holds) cannot be visible, no visible sample reads the value. Lanes
            // outside the lattice hold 0 anyway.
            const int8x in = inside(p);
            const int8x b = __builtin_convertvector(select8(in, p.x * per_brick, zero), int8x) * bi +
                            __builtin_convertvector(select8(in, p.y * per_brick, zero), int8x) * bj +
                            __builtin_convertvector(select8(in, p.z * per_brick, zero), int8x);
            if (!any8(in & bit_set8(skip->data(), b))) continue;
        }
        const float8 value = (density(p - along * offset) + density(p + along * offset)) * (0.5f * spacing * density_scale);
        float* to = out + 8 * q;
        if (8 * q + 8 <= width) {
            store8(to, load8(to) + value);
        } else {
            for (int l = 0; l < width - 8 * q; ++l) to[l] += value[l];
        }
        ++interpolated;
    }
    return interpolated;
}

}  // namespace pcvr
