#include "shaded/light/light_volume.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "shaded/light/extinction_field.h"
#include "shaded/light/penumbra.h"

namespace pcvr {

namespace {

Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
Vec3x8 lanes(const Vec3f& v) { return {broadcast8(v.x), broadcast8(v.y), broadcast8(v.z)}; }
float component(const Vec3& v, int a) { return float(a == 0 ? v.x : a == 1 ? v.y : v.z); }

/// The 32 bits at texels index and index + 1 of `texels`, per lane.
int8x gather_pairs(const uint16_t* texels, int8x index) {
#if defined(__AVX2__)
    return int8x(_mm256_i32gather_epi32(reinterpret_cast<const int*>(texels), __m256i(index), 2));
#else
    int8x out;
    for (int l = 0; l < 8; ++l) std::memcpy(&out[l], texels + index[l], 4);
    return out;
#endif
}

/// Texel coordinates of x in [0, n - 1]: the lower texel (at most n - 2) and the fraction beyond it.
struct Axis {
    int8x i0;
    float8 f;
    Axis(float8 x, int n) {
        const float8 clamped = clamp8(x, 0.0f, float(n - 1));
        i0 = __builtin_convertvector(min8(clamped, broadcast8(float(n - 2))), int8x);
        f = clamped - __builtin_convertvector(i0, float8);
    }
};

}  // namespace

LightVolume::LightVolume(const Light& light, const ExtinctionField& field, const Vec3& origin, double spacing, RenderControl& control,
                         float extinction_scale)
    : point_(light.kind == Light::Kind::Point), extinction_scale_(extinction_scale) {
    if (point_) {
        pivot_ = to_float(light.vector - origin);
        faces_.resize(6);
        for (int f = 0; f < 6; ++f) faces_[f].axis = f / 2, faces_[f].sign = f % 2 ? -1.0f : 1.0f;
    } else {
        const Vec3 d = light.vector / length(light.vector);
        Vec3 e1, e2;
        complete_frame(d, e1, e2);
        frame_[0] = to_float(e1), frame_[1] = to_float(e2), frame_[2] = to_float(d);
        faces_.resize(1);
    }
    // At most kMostTexels: the spacing grows by the cube root of the excess (and a little) until it fits.
    double h = spacing;
    for (uint64_t texels = lay_out(field.corners(), h); texels > kMostTexels; texels = lay_out(field.corners(), h))
        h *= std::cbrt(double(texels) / double(kMostTexels)) * 1.01;
    size_t total = 0;
    for (Face& f : faces_)
        if (f.used) f.offset = total, total += f.texels();
    transmittance_.assign(total + 1, kWhole);  // one more: a texel pair's read at the last texel
    spread_ = point_ ? 0.0f : float(std::tan(0.5 * light.angle));
    if (spread_ > 0) depth_.assign(total, 0.0f), occluder_.assign(total, 0.0f);
    for (const Face& f : faces_)
        if (f.used) integrate(f, field, control);
    if (spread_ > 0) {
        const Face& f = faces_[0];
        soften_penumbrae(transmittance_.data(), depth_.data(), occluder_.data(), SunLattice{f.nu, f.nv, f.nw, f.du, f.w0, f.dw},
                         spread_, kWhole, control);
        std::vector<float>().swap(depth_), std::vector<float>().swap(occluder_);
    }
}

uint64_t LightVolume::lay_out(const std::vector<Vec3>& corners, double h) {
    uint64_t total = 0;
    // Texels along one side, at most 2^30 (far-apart grids of tiny voxels): the caller coarsens h until they fit.
    auto count = [](float lo, float hi, float step) {
        return int(std::clamp(std::ceil(double(hi - lo) / step) + 1.0, 2.0, double(1 << 30)));
    };
    if (!point_) {
        Face& f = faces_[0];
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (const Vec3& c : corners)
            for (int k = 0; k < 3; ++k) {
                const float x = frame_[k].x * float(c.x) + frame_[k].y * float(c.y) + frame_[k].z * float(c.z);
                lo[k] = std::min(lo[k], x), hi[k] = std::max(hi[k], x);
            }
        f.used = true;
        f.u0 = lo[0], f.v0 = lo[1], f.w0 = lo[2];
        f.du = f.dv = f.dw = float(h);
        f.nu = count(lo[0], hi[0], f.du), f.nv = count(lo[1], hi[1], f.dv), f.nw = count(lo[2], hi[2], f.dw);
        return f.texels();
    }
    const Vec3 pivot{pivot_.x, pivot_.y, pivot_.z};
    for (Face& f : faces_) {
        // Depth z along the face's axis, and the ratios u = x1 / z, v = x2 / z of the two other axes.
        float z_lo = INFINITY, z_hi = -INFINITY, u_lo = INFINITY, u_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
        for (const Vec3& c : corners) {
            const Vec3 d = c - pivot;
            const float z = f.sign * component(d, f.axis);
            z_lo = std::min(z_lo, z), z_hi = std::max(z_hi, z);
            u_lo = std::min(u_lo, component(d, (f.axis + 1) % 3) / z), u_hi = std::max(u_hi, component(d, (f.axis + 1) % 3) / z);
            v_lo = std::min(v_lo, component(d, (f.axis + 2) % 3) / z), v_hi = std::max(v_hi, component(d, (f.axis + 2) % 3) / z);
        }
        f.used = z_hi > 0;
        if (!f.used) continue;
        // With every corner in front, the ratios' extremes over the boxes are at their corners (a ratio of
        // affine functions with a positive denominator); otherwise the whole pyramid.
        if (!(z_lo > 0)) u_lo = v_lo = -1, u_hi = v_hi = 1, z_lo = 0;
        f.u0 = std::max(u_lo, -1.0f), f.v0 = std::max(v_lo, -1.0f), f.w0 = z_lo;
        f.du = f.dv = float(h) / z_hi;  // h apart at the farthest depth, nearer ones closer
        f.dw = float(h);
        f.nu = count(f.u0, std::min(u_hi, 1.0f), f.du), f.nv = count(f.v0, std::min(v_hi, 1.0f), f.dv), f.nw = count(z_lo, z_hi, f.dw);
        total += f.texels();
    }
    return total;
}

Vec3x8 LightVolume::position(const Face& f, float8 u, float8 v, float w) const {
    if (!point_) return lanes(frame_[0]) * u + lanes(frame_[1]) * v + lanes(frame_[2]) * w;
    // d[axis] = sign z, d[axis + 1] = u z, d[axis + 2] = v z.
    const float8 along = broadcast8(f.sign * w), first = u * w, second = v * w;
    const float8 d[3] = {f.axis == 0 ? along : f.axis == 1 ? second : first, f.axis == 1 ? along : f.axis == 2 ? second : first,
                         f.axis == 2 ? along : f.axis == 0 ? second : first};
    return {d[0] + pivot_.x, d[1] + pivot_.y, d[2] + pivot_.z};
}

void LightVolume::integrate(const Face& f, const ExtinctionField& field, RenderControl& control) {
    const int padded = (f.nu + 7) / 8 * 8;
    tbb::parallel_for(0, f.nv, [&](int iv) {
        control.throw_if_cancelled();
        // The previous texel's extinction and depth along each column of the row; the trapezoid between them.
        std::vector<float> sigma_before(padded, 0.0f), tau(padded, 0.0f), tau_w(padded, 0.0f);
        std::vector<uint16_t> whole(padded);
        const bool soft = spread_ > 0;
        const float v = f.v0 + iv * f.dv;
        for (int iw = 0; iw < f.nw; ++iw) {
            const float w = f.w0 + iw * f.dw;
            for (int iu = 0; iu < padded; iu += 8) {
                const float8 u = f.u0 + (lane_index8() + float(iu)) * f.du;
                const float8 sigma = field.at(position(f, u, broadcast8(v), w)) * extinction_scale_;
                // Along a point light's ray a texel step is dw times sqrt(1 + u^2 + v^2).
                const float8 step = point_ ? f.dw * sqrt8(1.0f + u * u + v * v) : broadcast8(f.dw);
                const float8 before = load8(sigma_before.data() + iu);
                const float8 depth = iw == 0 ? broadcast8(0.0f) : load8(tau.data() + iu) + 0.5f * (before + sigma) * step;
                if (soft) {
                    // The depth-weighted mean w of what shadows the texel (penumbra.h), its own w where nothing does.
                    const float8 moment = load8(tau_w.data() + iu) + (depth - load8(tau.data() + iu)) * (w - 0.5f * f.dw);
                    store8(tau_w.data() + iu, moment);
                    const size_t at = f.offset + (size_t(iv) * f.nw + iw) * f.nu + iu;
                    for (int l = 0; l < 8 && iu + l < f.nu; ++l) {
                        depth_[at + l] = depth[l];
                        occluder_[at + l] = depth[l] > 1e-6f ? moment[l] / depth[l] : w;
                    }
                }
                store8(tau.data() + iu, depth);
                store8(sigma_before.data() + iu, sigma);
                const int8x rounded = __builtin_convertvector(exp8(-depth) * kWhole + 0.5f, int8x);
                for (int l = 0; l < 8; ++l) whole[iu + l] = uint16_t(rounded[l]);
            }
            std::memcpy(transmittance_.data() + f.offset + (size_t(iv) * f.nw + iw) * f.nu, whole.data(), sizeof(uint16_t) * f.nu);
        }
    });
}

float8 LightVolume::transmittance(const Face& f, float8 u, float8 v, float8 w) const {
    const Axis a{(u - f.u0) * (1.0f / f.du), f.nu}, b{(v - f.v0) * (1.0f / f.dv), f.nv}, c{(w - f.w0) * (1.0f / f.dw), f.nw};
    const int8x base = (b.i0 * f.nw + c.i0) * f.nu + a.i0;
    const uint16_t* t = transmittance_.data() + f.offset;
    const size_t sw = size_t(f.nu), sv = size_t(f.nu) * f.nw;
    auto lerp = [](float8 x, float8 y, float8 s) { return x + s * (y - x); };
    // One 32-bit read holds a texel and its neighbour along u (little-endian: the texel in the low half).
    auto edge = [&](size_t at) {
        const int8x pair = gather_pairs(t + at, base);
        return lerp(__builtin_convertvector(pair & 0xffff, float8), __builtin_convertvector((pair >> 16) & 0xffff, float8), a.f);
    };
    return lerp(lerp(edge(0), edge(sw), c.f), lerp(edge(sv), edge(sv + sw), c.f), b.f) * (1.0f / kWhole);
}

float8 LightVolume::at(const Vec3x8& p) const {
    if (!point_) {
        const Face& f = faces_[0];
        return transmittance(f, dot(lanes(frame_[0]), p), dot(lanes(frame_[1]), p), dot(lanes(frame_[2]), p));
    }
    // The face of each lane: the axis along which it lies farthest from the light, and the side.
    const Vec3x8 d = p - lanes(pivot_);
    const float8 ax = abs8(d.x), ay = abs8(d.y), az = abs8(d.z);
    const int8x on_x = (ax >= ay) & (ax >= az), on_y = ~on_x & (ay >= az), on_z = ~on_x & ~on_y;
    const float8 z = max8(max8(ax, ay), az);
    const float8 per_z = select8(z > 0, 1.0f / z, broadcast8(0.0f));
    const float8 first = select8(on_x, d.y, select8(on_y, d.z, d.x)), second = select8(on_x, d.z, select8(on_y, d.x, d.y));
    const float8 along = select8(on_x, d.x, select8(on_y, d.y, d.z));
    float8 out = broadcast8(1.0f);  // a face that is not used has nothing in it
    for (int k = 0; k < 6; ++k) {
        const Face& f = faces_[k];
        if (!f.used) continue;
        const int8x axis = f.axis == 0 ? on_x : f.axis == 1 ? on_y : on_z;
        const int8x mine = axis & (f.sign > 0 ? along >= 0 : along < 0);
        if (!any8(mine)) continue;
        out = select8(mine, transmittance(f, first * per_z, second * per_z, z), out);
    }
    return out;
}

float LightVolume::at(const Vec3f& p) const { return at(lanes(p))[0]; }

LightVolumes::LightVolumes(const std::vector<ShadedVolume>& volumes, const Lighting& lighting, bool render_shadows,
                           bool ambient_occlusion, const Kernel& kernel, const Vec3& origin, RenderControl& control, int octaves) {
    const std::vector<Light>& lights = lighting.lights;
    const bool shadows = std::any_of(lights.begin(), lights.end(), [&](const Light& l) { return l.casts_shadow(render_shadows); });
    if (!shadows && !ambient_occlusion) return;
    const ExtinctionField field(volumes, kernel, origin);
    if (field.empty()) octaves = 1;
    octaves_.resize(size_t(std::max(octaves - 1, 0)));
    for (int k = 0; k < std::max(octaves, 1); ++k) {
        // Octave 0 is the lights' own shadow; octave k's extinction is b^k of it, on a lattice twice as coarse.
        const float scale = float(std::pow(double(OctaveFactors::extinction), k));
        const double spacing = (k == 0 ? 1.0 : 2.0) * field.smallest_spacing();
        std::vector<const LightTransmittance*>& per_light = k == 0 ? per_light_ : octaves_[k - 1].per_light;
        std::vector<const LightTransmittance*>& occluders = k == 0 ? occluders_ : octaves_[k - 1].occluders;
        auto add = [&](const Light& light, double h) {
            volumes_.push_back(std::make_unique<LightVolume>(light, field, origin, h, control, scale));
            return volumes_.back().get();
        };
        if (shadows)  // else per_light stays empty: no light casts a shadow
            for (const Light& light : lights)
                per_light.push_back(field.empty() || !light.casts_shadow(render_shadows) ? nullptr : add(light, spacing));
        if (ambient_occlusion && !field.empty())
            for (const Light& sun : ambient_occlusion_suns()) occluders.push_back(add(sun, 2.0 * spacing));
    }
}

int scattering_octaves(const std::vector<ShadedVolume>& volumes, const Lighting& lighting, bool render_shadows) {
    const bool shadows = std::any_of(lighting.lights.begin(), lighting.lights.end(),
                                     [&](const Light& l) { return l.casts_shadow(render_shadows); });
    if (!shadows && !any_ambient_occlusion(volumes, lighting)) return 1;
    int most = 1;
    for (const ShadedVolume& v : volumes) most = std::max(most, (v.material ? *v.material : lighting.material).octaves());
    return most;
}

LightVolumes::~LightVolumes() = default;

uint64_t LightVolumes::texels() const {
    uint64_t total = 0;
    for (const auto& v : volumes_) total += v->texels();
    return total;
}

}  // namespace pcvr
