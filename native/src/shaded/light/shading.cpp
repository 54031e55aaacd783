#include "pcvr/shading.h"

#include <cmath>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

/// Shader::kMostRadiance for what the constructor prepares in double.
float capped(double v) { return float(std::min(v, double(Shader::kMostRadiance))); }
Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
Vec3f capped(const Vec3& v) { return {capped(v.x), capped(v.y), capped(v.z)}; }

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool non_negative(const Vec3& v) { return v.x >= 0 && v.y >= 0 && v.z >= 0; }

}  // namespace

void Lighting::validate() const {
    if (!finite(ambient) || !non_negative(ambient)) throw InvalidArgument("ambient must be a colour of three numbers >= 0");
    const Shading& m = material;
    for (double k : {m.ambient, m.diffuse, m.specular, m.shininess})
        if (!std::isfinite(k) || k < 0)
            throw InvalidArgument("Shading: ambient, diffuse, specular and shininess must be finite and >= 0");
    if (!(std::abs(m.anisotropy) < 1)) throw InvalidArgument("Shading: anisotropy must lie strictly between -1 and 1");
    if (m.scattering_octaves < 1 || m.scattering_octaves > kMostScatteringOctaves)
        throw InvalidArgument("Shading: scattering_octaves must lie in [1, " + std::to_string(kMostScatteringOctaves) + "]");
    for (size_t i = 0; i < lights.size(); ++i) {
        const Light& l = lights[i];
        const std::string what = "light " + std::to_string(i) + ": ";
        if (!finite(l.vector)) throw InvalidArgument(what + (l.kind == Light::Kind::Sun ? "direction" : "position") + " is not finite");
        if (l.kind == Light::Kind::Sun && length(l.vector) == 0) throw InvalidArgument(what + "a sun needs a direction");
        if (!finite(l.color) || !non_negative(l.color)) throw InvalidArgument(what + "color must be three numbers >= 0");
        if (!std::isfinite(l.strength) || l.strength < 0) throw InvalidArgument(what + "strength must be finite and >= 0");
        if (!(l.angle >= 0 && l.angle < 3.14159)) throw InvalidArgument(what + "angle must be in [0, pi) radians");
        if (l.kind == Light::Kind::Point && l.angle != 0) throw InvalidArgument(what + "a point light has no angle");
    }
}

std::vector<Light> ambient_occlusion_suns() {
    std::vector<Light> suns;
    for (int axis = 0; axis < 3; ++axis)
        for (double sign : {1.0, -1.0}) {
            Vec3 travel;  // from the direction the light comes from
            (axis == 0 ? travel.x : axis == 1 ? travel.y : travel.z) = -sign;
            suns.push_back(Light::sun(travel, {1, 1, 1}, 1.0));
        }
    return suns;
}

Shader::Shader(const Lighting& lighting, const Vec3& origin, std::vector<const LightTransmittance*> transmittance,
               const AlbedoModulation* albedo, std::vector<const LightTransmittance*> occluders,
               std::vector<ScatteringOctave> octaves)
    : albedo_(albedo) {
    lighting.validate();
    if (!transmittance.empty() && transmittance.size() != lighting.lights.size())
        throw InvalidArgument("Shader: one transmittance per light, or none");
    if (!occluders.empty() && occluders.size() != ambient_occlusion_suns().size())
        throw InvalidArgument("Shader: one occluder per ambient occlusion direction, or none");
    if (lighting.material.ambient_occlusion) occluders_ = std::move(occluders);
    const Shading& m = lighting.material;
    for (ScatteringOctave& octave : octaves) {
        if (int(octaves_.size()) + 1 >= m.octaves()) break;
        if (octave.per_light.empty()) octave.per_light.assign(lighting.lights.size(), nullptr);
        if (octave.per_light.size() != lighting.lights.size()) throw InvalidArgument("Shader: one transmittance per light in each octave");
        if (!m.ambient_occlusion) octave.occluders.clear();
        octaves_.push_back(std::move(octave));
    }
    lit_ = m.lit;
    modulated_ = albedo_ != nullptr || !occluders_.empty();
    scatter_ = m.model == Shading::Model::Scatter;
    anisotropy_ = float(m.anisotropy);
    ambient_ = capped(scatter_ ? lighting.ambient : lighting.ambient * m.ambient);
    diffuse_ = capped(m.diffuse);
    specular_ = capped(m.specular);
    // Specular highlights through a table (linear interpolation: 1e-5 off at shininess 10).
    power_.resize(kPowerSteps + 2);
    for (int k = 0; k <= kPowerSteps; ++k) power_[k] = float(std::pow(double(k) / kPowerSteps, m.shininess));
    power_[kPowerSteps + 1] = power_[kPowerSteps];
    for (size_t i = 0; i < lighting.lights.size(); ++i) {
        const Light& l = lighting.lights[i];
        const bool point = l.kind == Light::Kind::Point;
        // A sun's direction is where its light goes: towards the light is the opposite way.
        const Vec3 vector = point ? l.vector - origin : -l.vector / length(l.vector);
        lights_.push_back({point, to_float(vector), capped(l.color * (scatter_ ? l.irradiance() : l.strength)), transmittance.empty() ? nullptr : transmittance[i]});
        modulated_ = modulated_ || lights_.back().transmittance != nullptr;
    }
}

namespace {
Vec3x8 times(const Vec3x8& a, const Vec3x8& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
/// Room for the transmittances of this many lights on the stack; more take the heap.
constexpr size_t kStackLights = 8;
}  // namespace

Vec3x8 Shader::shade_modulated(const Vec3x8& transfer_colour, const Vec3x8& gradient, const Vec3x8& to_eye,
                                const Vec3x8& position) const {
    const Vec3x8 colour = albedo_ ? times(transfer_colour, albedo_->at(position)) : transfer_colour;
    if (!lit_) return bounded(colour);
    float8 on_stack[kStackLights];  // unshadowed lights' entries stay unset: arriving() reads none of them
    std::vector<float8> on_heap(lights_.size() > kStackLights ? lights_.size() : 0);
    float8* transmittance = on_heap.empty() ? on_stack : on_heap.data();
    for (size_t i = 0; i < lights_.size(); ++i)
        if (lights_[i].transmittance) transmittance[i] = lights_[i].transmittance->at(position);
    return shade_lit(colour, gradient, to_eye, position, transmittance, ambient_share(position));
}

float8 Shader::ambient_share(const Vec3x8& position) const {
    if (occluders_.empty()) return broadcast8(1.0f);
    float8 sum = broadcast8(0.0f);
    for (const LightTransmittance* t : occluders_) sum += t->at(position);
    return sum * (1.0f / float(occluders_.size()));
}

namespace {
/// The Henyey-Greenstein phase function of anisotropy g for the unit vector towards the light `l` and the
/// way to the eye, normalised over the sphere as Cycles' is.
float8 henyey_greenstein(float g, const Vec3x8& l, const Vec3x8& to_eye) {
    const float numerator = float((1.0 - double(g) * g) / (4.0 * M_PI));
    // cos theta between the light's travel (-l) and the way to the eye.
    const float8 base = max8(1.0f + g * g + 2.0f * g * dot(l, to_eye), broadcast8(1e-12f));
    return numerator / (base * sqrt8(base));
}
}  // namespace

Vec3x8 Shader::scatter(const Vec3x8& colour, const Vec3x8& to_eye, const Vec3x8& position, const float8* transmittance,
                       float8 ambient_share) const {
    Vec3x8 radiance = lanes({0, 0, 0});
    for (size_t i = 0; i < lights_.size(); ++i) {
        const auto [l, energy] = arriving(lights_[i], position, transmittance + i);
        radiance = radiance + energy * henyey_greenstein(anisotropy_, l, to_eye);
    }
    const Vec3x8 c = bounded(colour);
    if (octaves_.empty()) radiance = radiance + lanes(ambient_) * ambient_share;
    else radiance = scatter_octaves(radiance, c, to_eye, position, transmittance, ambient_share);
    radiance = bounded(radiance);
    return bounded(Vec3x8{c.x * radiance.x, c.y * radiance.y, c.z * radiance.z});
}

Vec3x8 Shader::scatter_octaves(const Vec3x8& single, const Vec3x8& colour, const Vec3x8& to_eye, const Vec3x8& position,
                               const float8* transmittance, float8 ambient_share) const {
    Vec3x8 radiance = single, weight = lanes({1, 1, 1}), ambient = lanes({1, 1, 1}) * ambient_share;
    float g = anisotropy_;
    // With ambient occlusion, the share of the directions the medium occludes: light scattered once meets the
    // medium again about that often, so octave k (k more scatterings) takes it to the k-th power.
    const bool surrounded = !occluders_.empty();
    const float8 occluded = max8(1.0f - ambient_share, broadcast8(0.0f));
    float8 meets_again = broadcast8(1.0f);
    const float forgets = surrounded ? OctaveFactors::weighted_anisotropy : OctaveFactors::anisotropy;
    for (const ScatteringOctave& octave : octaves_) {
        weight = times(weight, colour) * OctaveFactors::contribution;
        g *= forgets;
        meets_again *= occluded;
        for (size_t i = 0; i < lights_.size(); ++i) {
            const LightTransmittance* t = octave.per_light[i];
            if (!t || !lights_[i].transmittance) continue;
            // Without the occluders, only the light the first octave misses: a medium too thin to shadow scatters
            // too little to add.
            const float8 extra = surrounded ? t->at(position) * meets_again
                                            : max8(t->at(position) - transmittance[i], broadcast8(0.0f));
            const auto [l, energy] = arriving(lights_[i], position, &extra);
            radiance = radiance + times(weight, energy * henyey_greenstein(g, l, to_eye));
        }
        if (!octave.occluders.empty()) {
            float8 share = broadcast8(0.0f);
            for (const LightTransmittance* t : octave.occluders) share += t->at(position);
            ambient = ambient + weight * (share * (1.0f / float(octave.occluders.size())));
        }
    }
    // The white furnace: the world's light, scattered any number of times, is at most what arrives unoccluded.
    const float8 one = broadcast8(1.0f);
    ambient = {min8(ambient.x, one), min8(ambient.y, one), min8(ambient.z, one)};
    return radiance + times(lanes(ambient_), ambient);
}

Vec3f Shader::shade(const Vec3f& transfer_colour, const Vec3f& gradient, const Vec3f& to_eye, const Vec3f& position) const {
    Vec3f colour = transfer_colour;
    if (albedo_) {
        const Vec3f a = albedo_->at(position);
        colour = {colour.x * a.x, colour.y * a.y, colour.z * a.z};
    }
    if (!lit_) {
        const Vec3x8 c = bounded(lanes(colour));
        return {c.x[0], c.y[0], c.z[0]};
    }
    // One sample: each shadowed light's transmittance read once, at the one point.
    std::vector<float8> transmittance(lights_.size());
    for (size_t i = 0; i < lights_.size(); ++i)
        if (lights_[i].transmittance) transmittance[i] = broadcast8(lights_[i].transmittance->at(position));
    const Vec3x8 lit = shade_lit(lanes(colour), lanes(gradient), lanes(to_eye), lanes(position), transmittance.data(),
                                 ambient_share(lanes(position)));
    return {lit.x[0], lit.y[0], lit.z[0]};
}

}  // namespace pcvr
