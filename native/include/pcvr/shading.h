/// @file shading.h
/// @brief Lights and the materials of shaded volume rendering: Blinn-Phong, two-sided as in VTK and 3D
/// Slicer, or single scattering with a Henyey-Greenstein phase function (Blender's Principled Volume);
/// and the light's transmittance through the volumes (shadows).
///
/// A sample of transfer-function colour c at a point with density gradient g is lit (Blinn-Phong) as
///
/// | term     | value                                                        |
/// |----------|--------------------------------------------------------------|
/// | ambient  | ka * ambient colour * c                                      |
/// | diffuse  | kd * sum over lights of E * max(0, n.l) * c                  |
/// | specular | ks * sum over lights of E * max(0, n.h)^shininess, where n.l > 0 (white highlights) |
///
/// n is g normalised and flipped to face the eye (two-sided lighting: a surface is lit from whichever
/// side it is seen, the way VTK's TwoSidedLighting does it); l points towards the light, h halves l and
/// the direction to the eye. E is the light's colour times its strength: for a sun everywhere, for a
/// point light divided by the squared distance. Where the gradient vanishes there is no normal and
/// only the ambient term remains (VTK does the same).
///
/// Single scattering (Shading::Model::Scatter) needs no normal: the transfer function's colour is the
/// albedo, and a sample's radiance is c * (ambient colour + sum over lights of pi E * T * p(cos theta)),
/// pi E the light's irradiance (Light::irradiance), p the Henyey-Greenstein phase function (1 - g^2) / (4 pi (1 + g^2 - 2 g cos theta)^1.5), normalised
/// over the sphere as Cycles' is, theta the angle between the light's direction of travel and the
/// direction to the eye, g the anisotropy (> 0 scatters forwards: bright looking into the light).
/// The ambient colour is the world's radiance, arriving from all around: the phase function integrates to 1
/// over the sphere, so it enters without a phase and without pi.
///
/// T is the fraction of a light's energy that reaches the sample through the volumes (1 without shadows):
/// each light that casts shadows has a LightTransmittance, which the renderer builds once per render.
///
/// Ambient occlusion (Shading::ambient_occlusion, both models): the ambient colour reaches a sample as
/// the world's light does in Cycles, through the volumes: times the mean of its transmittance towards
/// the six directions +-x, +-y, +-z (ambient_occlusion_suns), each as a sun's shadow to infinity.
///
/// Multiple scattering (Scatter, Shading::scattering_octaves n > 1): light that scattered more than once,
/// by Wrenninge's octaves (OctaveFactors; docs/how-it-works.md, "Multiple scattering"): octave k adds a^k c^k
/// times the single scattering term with the extinction scaled by b^k and the anisotropy by d^k, c the albedo,
/// read from transmittances built at that extinction (ScatteringOctave), and with ambient occlusion times
/// (1 - A)^k, A the mean of the occluders (how often scattered light meets the medium again), else only the
/// light octave 0 misses (Tk - T0). Lights without shadows scatter once;
/// the ambient light's octaves need ambient occlusion, and its sum never passes the ambient colour times c
/// (the white furnace: an unoccluded world lights no medium brighter than itself).
#pragma once

#include <vector>

#include "pcvr/lanes.h"
#include "pcvr/math.h"

namespace pcvr {

struct Vec3f {
    float x = 0, y = 0, z = 0;
};

struct Light {
    enum class Kind { Sun, Point };
    /// Whether the volumes attenuate the light on its way to each sample: Default follows the render's
    /// ShadedParams::shadows; On and Off decide for this light whatever the render says (the light wins).
    enum class Shadow { Default, On, Off };
    Kind kind = Kind::Sun;
    Vec3 vector{0, 0, -1};  ///< Sun: the direction the light travels (any length). Point: its position.
    Vec3 color{1, 1, 1};    ///< linear RGB
    /// Sun: the radiance of a white diffuse surface facing it, its irradiance over pi (Lambert's law), so
    /// that Blinn-Phong's kd * strength is that surface's radiance. Point: the same at distance 1.
    double strength = 1.0;
    Shadow shadow = Shadow::Default;
    /// Sun: the angular diameter of its disc in radians (Blender's Angle), which softens its shadows: a
    /// point sees the part of the disc the volumes leave uncovered. 0: a hard shadow.
    double angle = 0.0;

    static Light sun(const Vec3& direction, const Vec3& color, double strength) { return {Kind::Sun, direction, color, strength}; }
    static Light point(const Vec3& position, const Vec3& color, double strength) { return {Kind::Point, position, color, strength}; }
    bool casts_shadow(bool render_shadows) const { return shadow == Shadow::Default ? render_shadows : shadow == Shadow::On; }
    /// What scattering media receive (sun; point: at distance 1): pi times the strength, since a phase
    /// function normalised over the sphere, unlike Lambert's cosine, spreads irradiance without a 1/pi.
    double irradiance() const { return M_PI * strength; }
};

/// The material: Blinn-Phong coefficients (VTK's volume property, Slicer's shading presets), or single
/// scattering with anisotropy g in (-1, 1) (the Principled Volume's). Not lit: samples keep the transfer
/// function's colours (VTK's and Slicer's shading off).
struct Shading {
    enum class Model { BlinnPhong, Scatter };
    double ambient = 0.1, diffuse = 0.9, specular = 0.2, shininess = 10.0;  ///< Blinn-Phong only
    bool lit = true;
    Model model = Model::BlinnPhong;
    double anisotropy = 0.0;  ///< Scatter only: the Henyey-Greenstein g
    bool ambient_occlusion = false;  ///< the ambient light through the volumes (see above)
    /// Scatter only: octaves of multiple scattering (see above), 1: single scattering only.
    int scattering_octaves = 6;
    /// The octaves this material asks for: 1 unless it scatters and is lit.
    int octaves() const { return lit && model == Model::Scatter ? scattering_octaves : 1; }
};

/// The most octaves Shading::scattering_octaves may ask for.
constexpr int kMostScatteringOctaves = 16;

/// Wrenninge's factors per octave of multiple scattering: a (contribution), b (extinction), d (anisotropy).
/// Chosen against the path tracer on a white cloud of optical depths 1.4 to 56 across (docs/how-it-works.md,
/// "Multiple scattering"): 0.5, 0.5, 0.5 (the paper's example) left a dense cloud half as bright as it is.
/// Octaves weighted by the occluded share (ambient occlusion on) scatter isotropically, d = 0: measured 1.3 to
/// 3.1 dB nearer the path tracer than d = 0.5 at every density; without the weighting d = 0 lost 2 dB on thin media.
struct OctaveFactors {
    static constexpr float contribution = 0.7f, extinction = 0.5f, anisotropy = 0.5f, weighted_anisotropy = 0.0f;
};

class LightTransmittance;

/// One octave k >= 1 of multiple scattering: each light's transmittance (null: none) and the ambient
/// occluders' (empty: none), at the extinction scaled by b^k. Kept alive by the caller, as the Shader's others.
struct ScatteringOctave {
    std::vector<const LightTransmittance*> per_light, occluders;
};

/// Ambient occlusion's six directions as suns, light arriving from +x, -x, +y, -y, +z and -z.
std::vector<Light> ambient_occlusion_suns();

/// The fraction of one light's energy that reaches points through the volumes of a render. Positions
/// are relative to the Shader's origin. Implementations are immutable and safe to read from many threads.
class LightTransmittance {
public:
    virtual ~LightTransmittance() = default;
    virtual float8 at(const Vec3x8& position) const = 0;
    virtual float at(const Vec3f& position) const = 0;
};

/// A colour that multiplies the transfer function's at each point: a volume's albedo per voxel
/// (ShadedVolume::albedo_grids, src/shaded/light/albedo_field.h). Positions are relative to the Shader's origin.
/// Implementations are immutable and safe to read from many threads.
class AlbedoModulation {
public:
    virtual ~AlbedoModulation() = default;
    virtual Vec3x8 at(const Vec3x8& position) const = 0;
    virtual Vec3f at(const Vec3f& position) const = 0;
};

struct Lighting {
    std::vector<Light> lights;
    Vec3 ambient{0.1, 0.1, 0.1};  ///< ambient light colour (the world colour in Blender)
    Shading material;

    /// Throws InvalidArgument for non-finite or negative numbers and a sun without a direction.
    void validate() const;
};

/// Lighting prepared for one render: light directions normalised, colours times strengths, and a
/// table of x^shininess. Immutable and safe to use from many threads.
class Shader {
public:
    /// Positions passed to shade() are relative to `origin` (world): renderers pass them relative to
    /// the camera, so that float keeps its precision in scenes far from the world's origin.
    /// `transmittance`: empty, or one per light of `lighting` (null: that light casts no shadow); the
    /// caller keeps them alive as long as the shader. `albedo` (optional, kept alive likewise) multiplies
    /// every sample's colour before it is lit.
    /// `occluders`: empty, or the transmittances of ambient_occlusion_suns, kept alive likewise; read
    /// where the material asks for ambient occlusion.
    /// `octaves`: octaves 1, 2, ... of multiple scattering (as many as the caller built; the material reads
    /// up to its scattering_octaves - 1 of them).
    explicit Shader(const Lighting& lighting, const Vec3& origin = {}, std::vector<const LightTransmittance*> transmittance = {},
                    const AlbedoModulation* albedo = nullptr, std::vector<const LightTransmittance*> occluders = {},
                    std::vector<ScatteringOctave> octaves = {});

    /// The lit colour of eight samples: `colour` from the transfer function, `gradient` of the density
    /// (world space, any length or scale), `to_eye` (unit, from the sample towards the eye),
    /// `position` (world, relative to the shader's origin).
    /// Inline: the renderers' sample loops call it per eight samples, where a call and its arguments
    /// through memory had cost more than the lighting itself.
    __attribute__((always_inline)) Vec3x8 shade(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye,
                                                const Vec3x8& position) const;
    /// The same for one sample.
    Vec3f shade(const Vec3f& colour, const Vec3f& gradient, const Vec3f& to_eye, const Vec3f& position) const;

    /// Lighting's float stages stay below this: every operand finite, a product may overflow to infinity
    /// but never meets a zero as one (infinity times zero, NaN), and each sum is capped again before it
    /// is multiplied. A point light at a sample (irradiance 1e30 times its energy) or energies, materials
    /// and colours up to double's range then give bright but finite colours.
    static constexpr float kMostRadiance = 1e30f;

private:
    struct PreparedLight {
        bool point;
        Vec3f vector;  // sun: unit vector towards the light; point: position
        Vec3f energy;  // colour * strength (scattering: * irradiance())
        const LightTransmittance* transmittance;  // null: no shadow
    };
    static constexpr int kPowerSteps = 1024;
    static Vec3x8 bounded(const Vec3x8& v) {
        const float8 most = broadcast8(kMostRadiance);
        return {min8(v.x, most), min8(v.y, most), min8(v.z, most)};  // min8 also maps NaN to the bound
    }
    static Vec3x8 lanes(const Vec3f& v) { return Vec3x8{broadcast8(v.x), broadcast8(v.y), broadcast8(v.z)}; }
    struct Arriving {
        Vec3x8 towards;  // unit, from the samples towards the light
        Vec3x8 energy;   // what reaches them: colour * strength, over the squared distance, times the transmittance
    };
    /// shade() where an albedo, shadows or ambient occlusion modulate the samples, or nothing is lit.
    Vec3x8 shade_modulated(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye, const Vec3x8& position) const;
    /// The light at eight samples; `*transmittance` is read only where the light has one.
    static Arriving arriving(const PreparedLight& light, const Vec3x8& position, const float8* transmittance);
    /// shade() with each shadowed light's transmittance at the samples (lights_' order, unshadowed ones unread).
    /// `ambient_share`: the ambient light's share that reaches the samples (ambient occlusion; else 1).
    __attribute__((always_inline)) Vec3x8 shade_lit(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye,
                                                    const Vec3x8& position, const float8* transmittance, float8 ambient_share) const;
    Vec3x8 scatter(const Vec3x8& colour, const Vec3x8& to_eye, const Vec3x8& position, const float8* transmittance,
                   float8 ambient_share) const;
    /// The mean transmittance of the occluders at eight samples (1 without).
    float8 ambient_share(const Vec3x8& position) const;
    /// What octaves_ add to scatter()'s `radiance` (single scattering at the samples, before the albedo).
    Vec3x8 scatter_octaves(const Vec3x8& radiance, const Vec3x8& colour, const Vec3x8& to_eye, const Vec3x8& position,
                           const float8* transmittance, float8 ambient_share) const;
    std::vector<ScatteringOctave> octaves_;
    std::vector<PreparedLight> lights_;
    std::vector<const LightTransmittance*> occluders_;
    const AlbedoModulation* albedo_;
    bool lit_, scatter_;
    bool modulated_;  // an albedo, a shadowed light or ambient occlusion
    Vec3f ambient_;  // ka * ambient colour (Scatter: the ambient colour)
    float diffuse_, specular_;
    float anisotropy_;
    std::vector<float> power_;  // x^shininess at x = k / kPowerSteps, and one more
};

inline Vec3x8 Shader::shade(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye, const Vec3x8& position) const {
    if (!lit_ || modulated_) return shade_modulated(colour, gradient, to_eye, position);
    return shade_lit(colour, gradient, to_eye, position, nullptr, broadcast8(1.0f));
}

inline Shader::Arriving Shader::arriving(const PreparedLight& light, const Vec3x8& position, const float8* transmittance) {
    Vec3x8 l = lanes(light.vector), energy = lanes(light.energy);
    if (light.point) {
        l = l - position;
        const float8 d2 = max8(dot(l, l), broadcast8(1e-30f));
        l = l * (1.0f / sqrt8(d2));
        energy = bounded(energy * (1.0f / d2));
    }
    if (light.transmittance) energy = energy * *transmittance;
    return {l, energy};
}

inline Vec3x8 Shader::shade_lit(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye, const Vec3x8& position,
                                const float8* transmittance, float8 ambient_share) const {
    if (scatter_) return scatter(colour, to_eye, position, transmittance, ambient_share);
    Vec3x8 diffuse = lanes(ambient_) * ambient_share, specular = lanes({0, 0, 0});
    // Scaled by the power of two nearest its largest component's inverse before it is squared: the
    // gradients of densities near 1e30 or 1e-30, or of voxels 1e-12 units wide, square beyond float's
    // range. From the exponent's bits (capped, so that the scale stays a normal number), not a division:
    // the lighting is one chain of dependent steps per eight samples, and its length is its cost.
    const float8 largest = max8(max8(abs8(gradient.x), abs8(gradient.y)), abs8(gradient.z));
    const int8x has_normal = (largest > 0) & (largest < INFINITY);
    const int8x exponent = int8x(largest) & 0x7f800000;  // the bits, not the value
    const int8x capped = exponent > (253 << 23) ? int8x{} + (253 << 23) : exponent;
    const float8 scale = float8(0x7f000000 - capped);  // 2^(127 - e): largest times it lies in [1, 4)
    const Vec3x8 g = gradient * select8(has_normal, scale, broadcast8(0.0f));
    if (any8(has_normal) && !lights_.empty()) {
        // Two-sided: the normal faces the eye. No normal where the gradient vanishes: ambient only.
        // The normal's length and the half vector's are divided out of the dot products, so that
        // their square roots overlap.
        const float8 facing = select8(dot(g, to_eye) < 0, broadcast8(-1.0f), broadcast8(1.0f));
        const float8 per_length = select8(has_normal, facing / sqrt8(dot(g, g)), broadcast8(0.0f));
        for (size_t li = 0; li < lights_.size(); ++li) {
            const auto [l, energy] = arriving(lights_[li], position, lights_[li].transmittance ? transmittance + li : nullptr);
            const float8 n_dot_l = dot(g, l) * per_length;
            const float8 lit = select8(n_dot_l > 0, n_dot_l, broadcast8(0.0f));
            diffuse = diffuse + energy * (diffuse_ * lit);
            if (specular_ > 0) {
                const Vec3x8 h = l + to_eye;
                const float8 h2 = max8(dot(h, h), broadcast8(1e-30f));
                const float8 n_dot_h = clamp8(dot(g, h) * per_length / sqrt8(h2), 0.0f, 1.0f);
                const float8 x = n_dot_h * float(kPowerSteps);
                const int8x k = __builtin_convertvector(x, int8x);
                const float8 power = lerp_pairs8(power_.data(), k, x - __builtin_convertvector(k, float8));
                specular = specular + energy * select8(n_dot_l > 0, specular_ * power, broadcast8(0.0f));
            }
        }
    }
    diffuse = bounded(diffuse);
    specular = bounded(specular);
    const Vec3x8 c = bounded(colour);
    return bounded(Vec3x8{c.x * diffuse.x + specular.x, c.y * diffuse.y + specular.y, c.z * diffuse.z + specular.z});
}

}  // namespace pcvr
