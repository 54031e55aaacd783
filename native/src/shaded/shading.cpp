#include "pcvr/shading.h"

#include <cmath>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

/// Lighting's float stages stay below this: every operand finite, a product may overflow to infinity
/// but never meets a zero as one (infinity times zero, NaN), and each sum is capped again before it is
/// multiplied. A point light at a sample (irradiance 1e30 times its energy) or energies, materials and
/// colours up to double's range then give bright but finite colours.
constexpr float kMostRadiance = 1e30f;

float bounded(double v) { return float(std::min(v, double(kMostRadiance))); }
Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
Vec3f bounded(const Vec3& v) { return {bounded(v.x), bounded(v.y), bounded(v.z)}; }
Vec3x8 bounded(const Vec3x8& v) {
    const float8 most = broadcast8(kMostRadiance);
    return {min8(v.x, most), min8(v.y, most), min8(v.z, most)};  // min8 also maps NaN to the bound
}

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool non_negative(const Vec3& v) { return v.x >= 0 && v.y >= 0 && v.z >= 0; }

}  // namespace

void Lighting::validate() const {
    if (!finite(ambient) || !non_negative(ambient)) throw InvalidArgument("ambient must be a colour of three numbers >= 0");
    const Shading& m = material;
    for (double k : {m.ambient, m.diffuse, m.specular, m.shininess})
        if (!std::isfinite(k) || k < 0)
            throw InvalidArgument("Shading: ambient, diffuse, specular and shininess must be finite and >= 0");
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light& l = lights[i];
        const std::string what = "light " + std::to_string(i) + ": ";
        if (!finite(l.vector)) throw InvalidArgument(what + (l.kind == Light::Kind::Sun ? "direction" : "position") + " is not finite");
        if (l.kind == Light::Kind::Sun && length(l.vector) == 0) throw InvalidArgument(what + "a sun needs a direction");
        if (!finite(l.color) || !non_negative(l.color)) throw InvalidArgument(what + "color must be three numbers >= 0");
        if (!std::isfinite(l.strength) || l.strength < 0) throw InvalidArgument(what + "strength must be finite and >= 0");
    }
}

Shader::Shader(const Lighting& lighting, const Vec3& origin) {
    lighting.validate();
    const Shading& m = lighting.material;
    lit_ = m.lit;
    ambient_ = bounded(lighting.ambient * m.ambient);
    diffuse_ = bounded(m.diffuse);
    specular_ = bounded(m.specular);
    // Specular highlights through a table (linear interpolation: 1e-5 off at shininess 10).
    power_.resize(kPowerSteps + 2);
    for (int k = 0; k <= kPowerSteps; ++k) power_[k] = float(std::pow(double(k) / kPowerSteps, m.shininess));
    power_[kPowerSteps + 1] = power_[kPowerSteps];
    for (const Light& l : lighting.lights) {
        const bool point = l.kind == Light::Kind::Point;
        // A sun's direction is where its light goes: towards the light is the opposite way.
        const Vec3 vector = point ? l.vector - origin : -l.vector / length(l.vector);
        lights_.push_back({point, to_float(vector), bounded(l.color * l.strength)});
    }
}

Vec3x8 Shader::shade(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye, const Vec3x8& position) const {
    if (!lit_) return bounded(colour);
    auto splat = [](const Vec3f& v) { return Vec3x8{broadcast8(v.x), broadcast8(v.y), broadcast8(v.z)}; };
    Vec3x8 diffuse = splat(ambient_), specular = splat({0, 0, 0});
    // Divided by its largest component before it is squared: the gradients of densities near 1e30
    // or 1e-30, or of voxels 1e-12 units wide, square beyond float's range.
    const float8 largest = max8(max8(abs8(gradient.x), abs8(gradient.y)), abs8(gradient.z));
    const int8x has_normal = (largest > 0) & (largest < INFINITY);
    const Vec3x8 g = gradient * select8(has_normal, 1.0f / largest, broadcast8(0.0f));
    if (any8(has_normal) && !lights_.empty()) {
        // Two-sided: the normal faces the eye. No normal where the gradient vanishes: ambient only.
        const float8 facing = select8(dot(g, to_eye) < 0, broadcast8(-1.0f), broadcast8(1.0f));
        const Vec3x8 n = g * select8(has_normal, facing / sqrt8(dot(g, g)), broadcast8(0.0f));
        for (const PreparedLight& light : lights_) {
            Vec3x8 l = splat(light.vector), energy = splat(light.energy);
            if (light.point) {
                l = l - position;
                const float8 d2 = max8(dot(l, l), broadcast8(1e-30f));
                l = l * (1.0f / sqrt8(d2));
                energy = bounded(energy * (1.0f / d2));
            }
            const float8 n_dot_l = dot(n, l);
            const float8 lit = select8(n_dot_l > 0, n_dot_l, broadcast8(0.0f));
            diffuse = diffuse + energy * (diffuse_ * lit);
            if (specular_ > 0) {
                const Vec3x8 h = l + to_eye;
                const float8 h2 = max8(dot(h, h), broadcast8(1e-30f));
                const float8 n_dot_h = clamp8(dot(n, h) / sqrt8(h2), 0.0f, 1.0f);
                const float8 x = n_dot_h * float(kPowerSteps);
                const int8x k = __builtin_convertvector(x, int8x);
                const float8 below = gather8(power_.data(), k), above = gather8(power_.data() + 1, k);
                const float8 power = below + (x - __builtin_convertvector(k, float8)) * (above - below);
                specular = specular + energy * select8(n_dot_l > 0, specular_ * power, broadcast8(0.0f));
            }
        }
    }
    diffuse = bounded(diffuse);
    specular = bounded(specular);
    const Vec3x8 c = bounded(colour);
    return bounded(Vec3x8{c.x * diffuse.x + specular.x, c.y * diffuse.y + specular.y, c.z * diffuse.z + specular.z});
}

Vec3f Shader::shade(const Vec3f& colour, const Vec3f& gradient, const Vec3f& to_eye, const Vec3f& position) const {
    auto lanes = [](const Vec3f& v) { return Vec3x8{broadcast8(v.x), broadcast8(v.y), broadcast8(v.z)}; };
    const Vec3x8 lit = shade(lanes(colour), lanes(gradient), lanes(to_eye), lanes(position));
    return {lit.x[0], lit.y[0], lit.z[0]};
}

}  // namespace pcvr
