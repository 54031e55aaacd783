/// @file shading.h
/// @brief Lights and the Blinn-Phong material of shaded volume rendering, two-sided as in VTK and 3D Slicer.
///
/// A sample of transfer-function colour c at a point with density gradient g is lit as
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
#pragma once

#include <vector>

#include "pcvr/lanes.h"
#include "pcvr/math.h"

namespace pcvr {

struct Light {
    enum class Kind { Sun, Point };
    Kind kind = Kind::Sun;
    Vec3 vector{0, 0, -1};  ///< Sun: the direction the light travels (any length). Point: its position.
    Vec3 color{1, 1, 1};    ///< linear RGB
    double strength = 1.0;  ///< Sun: irradiance. Point: intensity (irradiance at distance 1).

    static Light sun(const Vec3& direction, const Vec3& color, double strength) { return {Kind::Sun, direction, color, strength}; }
    static Light point(const Vec3& position, const Vec3& color, double strength) { return {Kind::Point, position, color, strength}; }
};

/// The material: Blinn-Phong coefficients (VTK's volume property, Slicer's shading presets). Not lit:
/// samples keep the transfer function's colours (VTK's and Slicer's shading off).
struct Shading {
    double ambient = 0.1, diffuse = 0.9, specular = 0.2, shininess = 10.0;
    bool lit = true;
};

struct Lighting {
    std::vector<Light> lights;
    Vec3 ambient{0.1, 0.1, 0.1};  ///< ambient light colour (the world colour in Blender)
    Shading material;

    /// Throws InvalidArgument for non-finite or negative numbers and a sun without a direction.
    void validate() const;
};

struct Vec3f {
    float x = 0, y = 0, z = 0;
};

/// Lighting prepared for one render: light directions normalised, colours times strengths, and a
/// table of x^shininess. Immutable and safe to use from many threads.
class Shader {
public:
    /// Positions passed to shade() are relative to `origin` (world): renderers pass them relative to
    /// the camera, so that float keeps its precision in scenes far from the world's origin.
    explicit Shader(const Lighting& lighting, const Vec3& origin = {});

    /// The lit colour of eight samples: `colour` from the transfer function, `gradient` of the density
    /// (world space, any length or scale), `to_eye` (unit, from the sample towards the eye),
    /// `position` (world, relative to the shader's origin).
    Vec3x8 shade(const Vec3x8& colour, const Vec3x8& gradient, const Vec3x8& to_eye, const Vec3x8& position) const;
    /// The same for one sample.
    Vec3f shade(const Vec3f& colour, const Vec3f& gradient, const Vec3f& to_eye, const Vec3f& position) const;

private:
    struct PreparedLight {
        bool point;
        Vec3f vector;  // sun: unit vector towards the light; point: position
        Vec3f energy;  // colour * strength
    };
    static constexpr int kPowerSteps = 1024;
    std::vector<PreparedLight> lights_;
    bool lit_;
    Vec3f ambient_;  // ka * ambient colour
    float diffuse_, specular_;
    std::vector<float> power_;  // x^shininess at x = k / kPowerSteps, and one more
};

}  // namespace pcvr
