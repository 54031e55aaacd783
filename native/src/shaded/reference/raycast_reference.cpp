#include "shaded/reference/raycast_reference.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <unordered_map>

#include "pcvr/errors.h"
#include "pcvr/kernel.h"
#include "pcvr/transfer_function.h"
#include "shaded/classify/emission.h"
#include "shaded/classify/sample_clip.h"
#include "shaded/classify/shaded_levels.h"
#include "shaded/light/albedo_field.h"
#include "shaded/light/light_volume.h"
#include "shaded/reference/path_tracer.h"
#include "shaded/sheets/compositing.h"
#include "shaded/sheets/sheet_walk.h"
#include "shaded/sheets/slab_splat.h"

namespace pcvr {

namespace {

/// Voxel values less the background by index coordinates, through a hash map of the grid's blocks.
class VoxelLookup {
public:
    explicit VoxelLookup(const Grid& grid) : background_(grid.background()) {
        for (const VoxelBlock& b : grid.blocks()) blocks_.emplace(key(b.origin[0], b.origin[1], b.origin[2]), &b);
    }
    /// The value of voxel (i, j, k) less the background, 0 when it is inactive or not finite.
    double departure(int64_t i, int64_t j, int64_t k) const {
        const int64_t bi = i & ~int64_t(7), bj = j & ~int64_t(7), bk = k & ~int64_t(7);
        const auto it = blocks_.find(key(bi, bj, bk));
        if (it == blocks_.end()) return 0.0;
        const VoxelBlock& b = *it->second;
        const int offset = int(((i - bi) << 6) | ((j - bj) << 3) | (k - bk));
        const float v = b.value(offset);
        const double d = double(v) - background_;
        return b.active(offset) && std::isfinite(d) ? d : 0.0;
    }
    double background() const { return background_; }

private:
    static uint64_t key(int64_t i, int64_t j, int64_t k) {
        return (uint64_t(i >> 3) & 0x1fffff) << 42 | (uint64_t(j >> 3) & 0x1fffff) << 21 | (uint64_t(k >> 3) & 0x1fffff);
    }
    std::unordered_map<uint64_t, const VoxelBlock*> blocks_;
    double background_;
};

/// One grid as the ray caster sees it.
struct RayGrid {
    const Grid* grid;
    Mat4 world_to_index;
    VoxelLookup voxels;
    double scale;
    std::array<double, 6> box;  // index bounding box widened by the kernel radius
    const ClassificationTable* classification;  // null for MIP
    const Shader* shader;                       // null for MIP
    std::optional<SampleClip> clip;             // relative to the geometry's origin0
};

struct DensitySample {
    bool reached = false;  // some active voxel other than the background is within the kernel's reach
    double density = 0;
    Vec3 gradient;  // world space
};

/// The reconstructed density at world point x, and its gradient: the background plus the voxels'
/// departures from it, as the splats reconstruct.
DensitySample sample(const RayGrid& g, const Kernel& kernel, const Vec3& x) {
    const Vec3 u = g.world_to_index.transform_point(x);
    const double R = kernel.radius();
    DensitySample out;
    Vec3 gradient_index;
    for (int64_t i = int64_t(std::ceil(u.x - R)); i <= int64_t(std::floor(u.x + R)); ++i)
        for (int64_t j = int64_t(std::ceil(u.y - R)); j <= int64_t(std::floor(u.y + R)); ++j)
            for (int64_t k = int64_t(std::ceil(u.z - R)); k <= int64_t(std::floor(u.z + R)); ++k) {
                const Vec3 d = u - Vec3{double(i), double(j), double(k)};
                const double r = length(d);
                if (r >= R) continue;
                const double v = g.voxels.departure(i, j, k);
                if (v == 0.0) continue;
                out.density += v * kernel.value(r);
                if (r > 0) gradient_index = gradient_index + d * (v * kernel.derivative(r) / r);
            }
    out.reached = out.density != 0.0;
    out.density = (out.density + (out.reached ? g.voxels.background() : 0.0)) * g.scale;
    // d/dx of f(B x + b) is B^T grad_u f.
    const Mat4& b = g.world_to_index;
    out.gradient = Vec3{b.m[0][0] * gradient_index.x + b.m[1][0] * gradient_index.y + b.m[2][0] * gradient_index.z,
                        b.m[0][1] * gradient_index.x + b.m[1][1] * gradient_index.y + b.m[2][1] * gradient_index.z,
                        b.m[0][2] * gradient_index.x + b.m[1][2] * gradient_index.y + b.m[2][2] * gradient_index.z} *
                   g.scale;
    return out;
}

/// The depths [near, far] at which the ray point(z) = origin + z dir lies in a grid's widened box.
bool ray_box_depths(const RayGrid& g, const Vec3& origin, const Vec3& dir, double& z0, double& z1) {
    const Vec3 o = g.world_to_index.transform_point(origin), d = g.world_to_index.transform_vector(dir);
    for (int a = 0; a < 3; ++a) {
        const double lo = g.box[a], hi = g.box[a + 3];
        if (d[a] == 0.0) {
            if (o[a] < lo || o[a] > hi) return false;
            continue;
        }
        double t0 = (lo - o[a]) / d[a], t1 = (hi - o[a]) / d[a];
        if (t0 > t1) std::swap(t0, t1);
        z0 = std::max(z0, t0);
        z1 = std::min(z1, t1);
    }
    return z0 <= z1;
}

/// The reference's shadows: from a sample, a ray towards the light through every grid's reconstruction (the
/// kernel sums, as the view rays see them), classified by its transfer function, outside its clip region
/// nothing; midpoint steps of at most `step` world units from where it enters the first grid's box to where
/// it leaves the last one (a sun) or meets the light.
class ShadowRays final : public LightTransmittance {
public:
    /// Reads `grids` when asked, not before: the Marcher fills them after it made its shaders.
    /// `extinction_scale` multiplies the extinction (an octave of multiple scattering).
    ShadowRays(const Light& light, const std::vector<RayGrid>& grids, const Kernel& kernel, const Vec3& origin, double step,
               double extinction_scale = 1.0)
        : light_(light), grids_(grids), kernel_(kernel), origin_(origin), step_(step), extinction_scale_(extinction_scale) {}

    float at(const Vec3f& position) const override {
        const Vec3 x = origin_ + Vec3{position.x, position.y, position.z};
        Vec3 dir = light_.kind == Light::Kind::Sun ? -light_.vector : light_.vector - x;
        const double reach = light_.kind == Light::Kind::Sun ? INFINITY : length(dir);
        if (!(length(dir) > 0)) return 1.0f;
        dir = dir / length(dir);
        if (!(light_.angle > 0)) return along(x, dir, reach);
        // A sun's disc: rays to kDiscPoints points spread evenly over it (Vogel's spiral), their mean.
        constexpr int kDiscPoints = 32;
        Vec3 e1, e2;
        complete_frame(dir, e1, e2);
        const double radius = std::tan(0.5 * light_.angle), golden = 2.39996322972865332;
        double sum = 0;
        for (int k = 0; k < kDiscPoints; ++k) {
            const double r = radius * std::sqrt((k + 0.5) / kDiscPoints), phi = k * golden;
            const Vec3 d = dir + e1 * (r * std::cos(phi)) + e2 * (r * std::sin(phi));
            sum += along(x, d / length(d), reach);
        }
        return float(sum / kDiscPoints);
    }
    float8 at(const Vec3x8& position) const override {
        float8 out;
        for (int l = 0; l < 8; ++l)  // one sample's eight lanes (Shader::shade of one Vec3f): one ray
            out[l] = l > 0 && position.x[l] == position.x[0] && position.y[l] == position.y[0] && position.z[l] == position.z[0]
                         ? out[0]
                         : at(Vec3f{position.x[l], position.y[l], position.z[l]});
        return out;
    }

private:
    static constexpr double kOpaqueDepth = 30;  // exp(-30): nothing more to see
    /// The transmittance from x along the unit direction `dir` up to `reach`.
    float along(const Vec3& x, const Vec3& dir, double reach) const {
        double from = INFINITY, to = -INFINITY;
        for (const RayGrid& g : grids_) {
            double a = 0, b = reach;
            if (ray_box_depths(g, x, dir, a, b)) from = std::min(from, a), to = std::max(to, b);
        }
        if (!(from < to)) return 1.0f;
        const int64_t steps = int64_t(std::ceil((to - from) / step_));
        const double ds = (to - from) / double(steps);
        double tau = 0;
        for (int64_t k = 0; k < steps && tau * extinction_scale_ < kOpaqueDepth; ++k) {
            const Vec3 p = x + dir * (from + (double(k) + 0.5) * ds);
            for (const RayGrid& g : grids_) {
                if (g.clip && !g.clip->inside<double>(p - origin_)) continue;
                const DensitySample s = sample(g, kernel_, p);
                if (s.reached) tau += double((*g.classification)(float(s.density)).extinction) * ds;
            }
        }
        return float(std::exp(-tau * extinction_scale_));
    }

    Light light_;
    const std::vector<RayGrid>& grids_;
    const Kernel& kernel_;
    Vec3 origin_;
    double step_, extinction_scale_;
};

/// Calls fn(pixel_index, px, py) for the sampled pixels, in parallel over rows.
template <class Fn>
void for_each_pixel(const Camera& camera, int step, RenderControl& control, Fn&& fn) {
    const int cols = (camera.width() + step - 1) / step, rows = (camera.height() + step - 1) / step;
    control.begin_phase(uint64_t(rows), 0.0, 1.0);
    tbb::parallel_for(0, rows, [&](int r) {
        control.throw_if_cancelled();
        for (int c = 0; c < cols; ++c) fn(size_t(r) * cols + c, double(c) * step, double(r) * step);
        control.advance();
    });
    control.throw_if_cancelled();
}

/// What both modes share: the grids, the kernel, the sample spacing and the rays.
struct Marcher {
    Kernel kernel;
    std::vector<ClassificationTable> tables;
    std::vector<std::unique_ptr<ShadowRays>> shadow_rays;
    std::vector<Shader> shaders;
    std::vector<std::unique_ptr<AlbedoField>> albedos;
    std::vector<RayGrid> grids;
    SheetGeometry geometry;
    double near_depth, far_depth, step;

    /// `lighting` null: MIP.
    Marcher(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params, const Lighting* lighting)
        : kernel(Kernel::from_name(params.splat_kernel)), geometry(camera) {
        if (params.pixel_step < 1) throw InvalidArgument("pixel_step must be at least 1");
        double spacing = INFINITY;
        tables.reserve(volumes.size());  // grids point into both
        shaders.reserve(volumes.size());
        grids.reserve(volumes.size());
        // Shadow rays step sheet_spacing of the finest grid's voxels.
        double finest = INFINITY;
        for (const ShadedVolume& v : volumes)
            if (v.grid->active_voxel_count() > 0) finest = std::min(finest, smallest_voxel_spacing(*v.grid));
        // Per octave of multiple scattering (0: the lights' own shadows), shadow rays towards each shadowed light
        // and, with ambient occlusion, towards its six directions, at the octave's extinction.
        const int octaves = lighting && std::isfinite(finest) ? scattering_octaves(volumes, *lighting, params.shadows) : 1;
        std::vector<ScatteringOctave> rays(static_cast<size_t>(octaves));
        for (int k = 0; k < octaves && lighting && std::isfinite(finest); ++k) {
            const double scale = std::pow(double(OctaveFactors::extinction), k);
            auto add = [&](const Light& light) {
                shadow_rays.push_back(std::make_unique<ShadowRays>(light, grids, kernel, geometry.origin0, finest * params.sheet_spacing, scale));
                return shadow_rays.back().get();
            };
            for (const Light& light : lighting->lights) rays[k].per_light.push_back(light.casts_shadow(params.shadows) ? add(light) : nullptr);
            if (std::all_of(rays[k].per_light.begin(), rays[k].per_light.end(), [](auto* t) { return t == nullptr; })) rays[k].per_light.clear();
            if (any_ambient_occlusion(volumes, *lighting))
                for (const Light& sun : ambient_occlusion_suns()) rays[k].occluders.push_back(add(sun));
        }
        const std::vector<const LightTransmittance*> shadowed = rays.front().per_light, occluders = rays.front().occluders;
        rays.erase(rays.begin());
        for (const ShadedVolume& v : volumes) {
            const Grid& grid = *v.grid;
            if (grid.active_voxel_count() == 0) continue;
            const ViewProjection projection(camera, grid.index_to_world());
            spacing = std::min(spacing, depth_per_voxel(projection, grid, SheetLattice()));
            const Mat4 to_index = *grid.index_to_world().inverse();
            const auto b = grid.index_bbox();
            const double R = kernel.radius();
            const ClassificationTable* table = nullptr;
            const Shader* shader = nullptr;
            if (lighting) {
                const TransferFunction& tf = *v.transfer_function;
                const double unit = tf.unit_distance > 0 ? tf.unit_distance : smallest_voxel_spacing(grid);
                tables.emplace_back(tf, unit);
                table = &tables.back();
                albedos.push_back(AlbedoField::of(v, geometry.origin0));
                shaders.emplace_back(v.lit_by(*lighting), geometry.origin0, shadowed, albedos.back().get(), occluders, rays);
                shader = &shaders.back();
            }
            std::optional<SampleClip> clip;
            if (v.clip && !v.clip->keeps_everything()) clip.emplace(*v.clip, geometry.origin0, smallest_voxel_spacing(grid));
            grids.push_back({&grid, to_index, VoxelLookup(grid), v.density_scale,
                             {b[0] - R, b[1] - R, b[2] - R, b[3] + R, b[4] + R, b[5] + R}, table, shader, std::move(clip)});
        }
        step = spacing * params.sheet_spacing;
        const Mat4& w2c = camera.world_to_camera();
        auto depth_of = [&](const Vec3& p) { return -(w2c.m[2][0] * p.x + w2c.m[2][1] * p.y + w2c.m[2][2] * p.z + w2c.m[2][3]); };
        const Ray r = camera.pixel_ray(0.5 * (camera.width() - 1), 0.5 * (camera.height() - 1));
        near_depth = depth_of(r.origin);
        far_depth = depth_of(r.origin + r.direction);
    }

    /// Calls fn(point, depth) for the samples of the ray through (px, py) that lie in some grid's box,
    /// front to back, until fn returns false.
    template <class Fn>
    void march(double px, double py, Fn&& fn) const {
        const Vec3 origin = geometry.origin0 + geometry.origin_dx * px + geometry.origin_dy * py;
        const Vec3 dir = geometry.direction(px, py);
        double z0 = INFINITY, z1 = -INFINITY;
        for (const RayGrid& g : grids) {
            double a = near_depth, b = far_depth;
            if (ray_box_depths(g, origin, dir, a, b)) z0 = std::min(z0, a), z1 = std::max(z1, b);
        }
        if (!(z0 <= z1)) return;
        const int64_t k0 = std::max<int64_t>(0, sheet_floor((z0 - near_depth) / step - 0.5));
        const int64_t k1 = -sheet_floor(-((z1 - near_depth) / step - 0.5));  // the ceiling
        for (int64_t k = k0; k <= k1; ++k) {
            const double z = near_depth + (double(k) + 0.5) * step;
            if (z > far_depth) break;
            if (!fn(origin + dir * z, z)) break;
        }
    }
};

Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }

/// The direction of v in a length float holds (gradients of densities near 1e30 exceed it).
Vec3 scale_free(const Vec3& v) {
    const double largest = std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
    return largest > 0 ? v / largest : v;
}

/// Gradient magnitudes (gradient opacity) are scaled by this: the analytic gradient of a truncated kernel
/// misses its jump h(R) at the rim, which the voxels crossing the rim add as the point moves, on average
/// h(R) 4/3 pi R^3 of a linear field's slope (3.7% for gauss1.4); the splats' differences include it.
double rim_compensation(const Kernel& kernel) {
    const double R = kernel.radius();
    const double missed = kernel.value(R * (1 - 1e-9)) * (4.0 / 3.0) * M_PI * R * R * R;
    return missed < 1 ? 1.0 / (1.0 - missed) : 1.0;  // the box: no gradient inside at all
}

/// Adds the emission of density `density`, times `share`, to `glow`: emitted whether or not it absorbs. Out of
/// line, so that the compiler leaves the arithmetic of transfer functions without emission as it was.
[[gnu::noinline]] Vec3 add_emission(const Vec3& glow, const ClassificationTable& table, double density, double share) {
    const ClassificationTable::Emission e = table.emission(float(density));
    return glow + Vec3{e.red, e.green, e.blue} * share;
}

/// Adds the light a sample emits (radiance `glow` per world unit, extinction `sigma` over `length`) to `acc`,
/// attenuated by the opacity `in_front` of what lies before the sample. Out of line, as add_emission.
[[gnu::noinline]] Rgba composite_emission(Rgba acc, float in_front, const Vec3& glow, double sigma, double length) {
    const double through = (1.0 - in_front) * emitted_length(sigma, length);
    acc.r += float(glow.x * through), acc.g += float(glow.y * through), acc.b += float(glow.z * through);
    return acc;
}

}  // namespace

void raycast_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                    const ShadedParams& params, RenderControl& control, float* rgba, float* depth) {
    if (params.paths > 0) return path_trace_shaded(volumes, camera, lighting, params, control, rgba);
    const Marcher m(volumes, camera, params, &lighting);
    const float cutoff = float(params.opacity_cutoff);
    const double rim = rim_compensation(m.kernel);
    for_each_pixel(camera, params.pixel_step, control, [&](size_t index, double px, double py) {
        const Vec3 dir = m.geometry.direction(px, py);
        const double length_per_step = m.step * length(dir);
        const Vec3f to_eye = to_float(dir * (-1.0 / length(dir)));
        Rgba acc;
        float half_way = INFINITY;
        m.march(px, py, [&](const Vec3& x, double z) {
            double sigma_sum = 0;
            Vec3 emission, glow;  // glow: the medium's own emitted radiance per world unit
            for (const RayGrid& g : m.grids) {
                // The share of the sample's step inside the grid's clip region (sample_clip.h).
                const Vec3 relative = x - m.geometry.origin0;
                const double share = g.clip ? g.clip->share<double>(relative, dir * (0.5 * m.step)) : 1.0;
                if (!(share > 0)) continue;
                const DensitySample s = sample(g, m.kernel, x);
                if (!s.reached) continue;
                const ClassificationTable::Sample c = (*g.classification)(float(s.density));
                if (g.classification->has_emission()) glow = add_emission(glow, *g.classification, s.density, share);
                if (!(c.extinction > 0)) continue;
                // Gradient opacity reads the field's gradient; a cut face is lit by the plane (sample_clip.h).
                const float opacity_extinction = g.classification->has_gradient_opacity()
                                                     ? g.classification->extinction(float(s.density), float(rim * length(s.gradient)))
                                                     : c.extinction;
                if (!(opacity_extinction > 0)) continue;
                const Vec3 gradient =
                    g.clip ? g.clip->face_gradient<double>(relative, scale_free(s.gradient),
                                                           g.clip->weak_gradient(length(s.gradient), s.density - g.voxels.background() * g.scale))
                           : scale_free(s.gradient);
                const Vec3f lit = g.shader->shade({c.red, c.green, c.blue}, to_float(gradient), to_eye, to_float(relative));
                const double extinction = double(opacity_extinction) * share;
                sigma_sum += extinction;
                emission = emission + Vec3{lit.x, lit.y, lit.z} * extinction;
            }
            const float in_front = acc.a;  // the emitted light passes what lies in front, not this sample
            if (sigma_sum > 0) {
                const float alpha = slab_opacity(float(sigma_sum), float(length_per_step));
                const float before = acc.a;
                composite_behind(acc, float(emission.x / sigma_sum), float(emission.y / sigma_sum), float(emission.z / sigma_sum), alpha);
                if (before < 0.5f && acc.a >= 0.5f) half_way = float(z);
            }
            if (glow.x > 0 || glow.y > 0 || glow.z > 0) acc = composite_emission(acc, in_front, glow, sigma_sum, length_per_step);
            return acc.a < cutoff;
        });
        float* out = rgba + 4 * index;
        out[0] = acc.r, out[1] = acc.g, out[2] = acc.b, out[3] = acc.a;
        if (depth) depth[index] = half_way;
    });
}

void raycast_mip(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params,
                 RenderControl& control, float* out) {
    const Marcher m(volumes, camera, params, nullptr);
    for_each_pixel(camera, params.pixel_step, control, [&](size_t index, double px, double py) {
        double maximum = mip_background(volumes);
        m.march(px, py, [&](const Vec3& x, double) {
            for (const RayGrid& g : m.grids) {
                if (g.clip && !g.clip->inside<double>(x - m.geometry.origin0)) continue;
                const DensitySample s = sample(g, m.kernel, x);
                if (s.reached) maximum = std::max(maximum, s.density);
            }
            return true;
        });
        out[index] = float(maximum);
    });
}

}  // namespace pcvr
