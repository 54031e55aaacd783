#include "shaded/reference/path_tracer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "pcvr/kernel.h"
#include "shaded/light/extinction_field.h"
#include "shaded/sheets/sheet_geometry.h"

namespace pcvr {

namespace {

constexpr int kRouletteAfter = 8, kMostVertices = 1024;
constexpr double kOpaqueDepth = 30;  // exp(-30): no light gets through

/// splitmix64: small, seedable per pixel, good enough for a reference.
class Random {
public:
    /// Streams start at scrambled points of the generator's cycle: pixel i's is not pixel 0's shifted by i draws.
    Random(uint64_t seed, uint64_t stream) : state_(mix(mix(seed) ^ stream)) {}
    double uniform() { return double(mix(state_ += kGolden) >> 11) * 0x1.0p-53; }  // in [0, 1)

private:
    static constexpr uint64_t kGolden = 0x9e3779b97f4a7c15ull;
    static uint64_t mix(uint64_t z) {
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }
    uint64_t state_;
};

Vec3 times(const Vec3& a, const Vec3& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }

/// The Henyey-Greenstein phase function for cos theta between the light's travel and the scattered direction.
double henyey_greenstein(double g, double cos_theta) {
    const double base = std::max(1 + g * g - 2 * g * cos_theta, 1e-12);
    return (1 - g * g) / (4 * M_PI * base * std::sqrt(base));
}

/// A direction drawn from the phase function around `d` (the way the path travels on).
Vec3 sample_direction(const Vec3& d, double g, Random& random) {
    const double u = random.uniform(), phi = 2 * M_PI * random.uniform();
    double cos_theta = 1 - 2 * u;
    if (std::abs(g) > 1e-3) {
        const double s = (1 - g * g) / (1 - g + 2 * g * u);
        cos_theta = std::clamp((1 + g * g - s * s) / (2 * g), -1.0, 1.0);
    }
    const double sin_theta = std::sqrt(std::max(0.0, 1 - cos_theta * cos_theta));
    Vec3 e1, e2;
    complete_frame(d, e1, e2);
    return d * cos_theta + e1 * (sin_theta * std::cos(phi)) + e2 * (sin_theta * std::sin(phi));
}

/// The volumes' extinction along rays inside their boxes (positions relative to the field's origin).
class Medium {
public:
    Medium(const ExtinctionField& field, double step) : field_(field), step_(step) {
        for (const Vec3& c : field.corners())
            for (int a = 0; a < 3; ++a) lo_[a] = std::min(lo_[a], c[a]), hi_[a] = std::max(hi_[a], c[a]);
    }

    /// Along x + t d (d unit) for t in [0, reach): the t at which the optical depth reaches `target`
    /// (INFINITY: never), or with target INFINITY the optical depth up to reach (at most kOpaqueDepth).
    double march(const Vec3& x, const Vec3& d, double reach, double target, double* depth = nullptr) const {
        double t0 = 0, t1 = reach;
        for (int a = 0; a < 3; ++a) {
            if (d[a] == 0) {
                if (x[a] < lo_[a] || x[a] > hi_[a]) t1 = -1;
                continue;
            }
            double a0 = (lo_[a] - x[a]) / d[a], a1 = (hi_[a] - x[a]) / d[a];
            if (a0 > a1) std::swap(a0, a1);
            t0 = std::max(t0, a0), t1 = std::min(t1, a1);
        }
        double tau = 0;
        for (double t = t0; t < t1 && tau < kOpaqueDepth; t += 8 * step_) {
            const float8 along = float(t) + (lane_index8() + 0.5f) * float(step_);
            const float8 sigma = field_.at(lanes3(x) + lanes3(d) * along);
            for (int l = 0; l < 8; ++l) {
                const double from = t + l * step_;
                if (from >= t1) break;
                const double ds = std::min(step_, t1 - from), grown = tau + double(sigma[l]) * ds;
                if (grown >= target) return from + (target - tau) / double(sigma[l]);
                tau = grown;
            }
        }
        if (depth) *depth = std::min(tau, kOpaqueDepth);
        return INFINITY;
    }
    double transmittance(const Vec3& x, const Vec3& d, double reach) const {
        double depth = 0;
        march(x, d, reach, INFINITY, &depth);
        return std::exp(-depth);
    }
    Vec3 albedo(const Vec3& x) const {
        const ExtinctionField::Medium m = field_.medium(lanes3(x));
        return {m.albedo.x[0], m.albedo.y[0], m.albedo.z[0]};
    }

private:
    const ExtinctionField& field_;
    double step_;
    double lo_[3] = {INFINITY, INFINITY, INFINITY}, hi_[3] = {-INFINITY, -INFINITY, -INFINITY};
};

/// One path's radiance towards the eye from the ray x + t d (t > 0).
Vec3 trace(const Medium& medium, const Lighting& lighting, const Vec3& origin, double g, Vec3 x, Vec3 d, Random& random) {
    Vec3 radiance, throughput{1, 1, 1};
    for (int vertex = 0; vertex < kMostVertices; ++vertex) {
        const double t = medium.march(x, d, INFINITY, -std::log(1 - random.uniform()));
        if (!std::isfinite(t)) {
            if (vertex > 0) radiance = radiance + times(throughput, lighting.ambient);
            break;
        }
        x = x + d * t;
        throughput = times(throughput, medium.albedo(x));
        for (const Light& light : lighting.lights) {
            // l: from x towards the light; the light travels along -l, then on along -d towards the eye.
            Vec3 l = light.kind == Light::Kind::Sun ? -light.vector : light.vector - origin - x;
            const double distance = length(l);
            if (!(distance > 0)) continue;
            l = l / distance;
            const double reach = light.kind == Light::Kind::Sun ? INFINITY : distance;
            const double falloff = light.kind == Light::Kind::Sun ? 1.0 : 1.0 / (distance * distance);
            const double energy = light.irradiance() * falloff * medium.transmittance(x, l, reach) * henyey_greenstein(g, dot(l, d));
            radiance = radiance + times(throughput, light.color) * energy;
        }
        const double most = std::max({throughput.x, throughput.y, throughput.z});
        if (!(most > 0)) break;
        if (vertex >= kRouletteAfter) {
            const double keep = std::min(1.0, most);
            if (random.uniform() >= keep) break;
            throughput = throughput / keep;
        }
        d = sample_direction(d, g, random);
    }
    return radiance;
}

}  // namespace

void path_trace_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                       const ShadedParams& params, RenderControl& control, float* rgba) {
    const SheetGeometry geometry(camera);
    const Kernel kernel = Kernel::from_name(params.splat_kernel);
    const ExtinctionField field(volumes, kernel, geometry.origin0);
    if (field.empty()) return;  // the image stays transparent
    const Medium medium(field, field.smallest_spacing() * params.sheet_spacing);
    const double g = volumes.empty() || !volumes[0].material ? lighting.material.anisotropy : volumes[0].material->anisotropy;
    // Rays start at the near clip plane, as the ray caster's samples do.
    const Mat4& w2c = camera.world_to_camera();
    const Ray centre = camera.pixel_ray(0.5 * (camera.width() - 1), 0.5 * (camera.height() - 1));
    const double near_depth = -(w2c.m[2][0] * centre.origin.x + w2c.m[2][1] * centre.origin.y + w2c.m[2][2] * centre.origin.z + w2c.m[2][3]);
    const int step = params.pixel_step, cols = (camera.width() + step - 1) / step, rows = (camera.height() + step - 1) / step;
    control.begin_phase(uint64_t(rows), 0.0, 1.0);
    tbb::parallel_for(0, rows, [&](int r) {
        control.throw_if_cancelled();
        for (int c = 0; c < cols; ++c) {
            const size_t index = size_t(r) * cols + c;
            const double px = double(c) * step, py = double(r) * step;
            const Vec3 along = geometry.direction(px, py), d = along / length(along);
            const Vec3 x = geometry.point(px, py, near_depth) - geometry.origin0;
            Random random(params.seed, index);
            Vec3 sum;
            for (int p = 0; p < params.paths; ++p) sum = sum + trace(medium, lighting, geometry.origin0, g, x, d, random);
            const double alpha = 1 - medium.transmittance(x, d, INFINITY);
            float* out = rgba + 4 * index;
            out[0] = float(sum.x / params.paths), out[1] = float(sum.y / params.paths), out[2] = float(sum.z / params.paths);
            out[3] = float(alpha);
        }
        control.advance();
    });
    control.throw_if_cancelled();
}

}  // namespace pcvr
