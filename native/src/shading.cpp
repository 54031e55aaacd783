#include "pcvr/shading.h"

#include <cmath>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

Vec3f to_float(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
inline float dot3(const Vec3f& a, const Vec3f& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

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

Shader::Shader(const Lighting& lighting) {
    lighting.validate();
    const Shading& m = lighting.material;
    ambient_ = to_float(lighting.ambient * m.ambient);
    diffuse_ = float(m.diffuse);
    specular_ = float(m.specular);
    shininess_ = float(m.shininess);
    for (const Light& l : lighting.lights) {
        const bool point = l.kind == Light::Kind::Point;
        // A sun's direction is where its light goes: towards the light is the opposite way.
        const Vec3 vector = point ? l.vector : -l.vector / length(l.vector);
        lights_.push_back({point, to_float(vector), to_float(l.color * l.strength)});
    }
}

Vec3f Shader::shade(const Vec3f& colour, const Vec3f& gradient, const Vec3f& to_eye, const Vec3f& position) const {
    Vec3f diffuse{ambient_.x, ambient_.y, ambient_.z}, specular{0, 0, 0};
    const float g2 = dot3(gradient, gradient);
    if (g2 > 0 && !lights_.empty()) {
        // Two-sided: the normal faces the eye.
        const float inv = (dot3(gradient, to_eye) < 0 ? -1.0f : 1.0f) / std::sqrt(g2);
        const Vec3f n{gradient.x * inv, gradient.y * inv, gradient.z * inv};
        for (const PreparedLight& light : lights_) {
            Vec3f l = light.vector, energy = light.energy;
            if (light.point) {
                l = {l.x - position.x, l.y - position.y, l.z - position.z};
                const float d2 = dot3(l, l);
                if (!(d2 > 0)) continue;
                const float inv_d = 1.0f / std::sqrt(d2), falloff = 1.0f / d2;
                l = {l.x * inv_d, l.y * inv_d, l.z * inv_d};
                energy = {energy.x * falloff, energy.y * falloff, energy.z * falloff};
            }
            const float n_dot_l = dot3(n, l);
            if (n_dot_l <= 0) continue;
            diffuse.x += diffuse_ * n_dot_l * energy.x;
            diffuse.y += diffuse_ * n_dot_l * energy.y;
            diffuse.z += diffuse_ * n_dot_l * energy.z;
            Vec3f h{l.x + to_eye.x, l.y + to_eye.y, l.z + to_eye.z};
            const float h2 = dot3(h, h);
            if (specular_ > 0 && h2 > 0) {
                const float n_dot_h = dot3(n, h) / std::sqrt(h2);
                if (n_dot_h > 0) {
                    const float s = specular_ * std::pow(n_dot_h, shininess_);
                    specular.x += s * energy.x;
                    specular.y += s * energy.y;
                    specular.z += s * energy.z;
                }
            }
        }
    }
    return {colour.x * diffuse.x + specular.x, colour.y * diffuse.y + specular.y, colour.z * diffuse.z + specular.z};
}

}  // namespace pcvr
