/// @file light_volume.h
/// @brief Shadows for the sheet renderers: each shadowed light's optical depth through all the volumes of a
/// render, integrated once per render on a lattice whose columns are the light's rays, then read by
/// every lit sample (trilinear, eight samples at a time).
///
/// | light | lattice                                                              | a column              |
/// |-------|----------------------------------------------------------------------|-----------------------|
/// | sun   | a box aligned with the light's direction, over the grids' boxes      | a ray, w along it     |
/// | point | up to six pyramids around the light (a cube map), each over u = x/z, | a ray from the light, |
/// |       | v = y/z of its axis z, restricted to the grids' boxes as seen from it | z along its axis      |
///
/// Along each column the optical depth is the trapezoidal sum of ExtinctionField's extinction at the
/// texels, one texel (the grids' smallest voxel spacing, or coarser under kMostTexels) apart: no
/// resampling from one slice to the next, so shadows stay as sharp as the lattice, whatever the light's
/// angle (sweeps that interpolate the previous slice blur them a little more at every step). Texels hold
/// the transmittance exp(-depth), which a sample reads trilinearly and multiplies its light by: inside
/// bone the depth climbs by several units per voxel, and interpolating it (then exp) darkened the lit
/// side of a CT head's skull, 4.7 dB further from the ray caster than interpolating the transmittance
/// (tests/bench/shadows_bench.py; on the translucent phantom the two are within 0.5 dB). Points nearer
/// to the light than the lattice get all of it (nothing lies there); points beyond it, its edge's.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/kernel.h"
#include "pcvr/render_control.h"
#include "pcvr/shaded.h"
#include "pcvr/shading.h"

namespace pcvr {

class ExtinctionField;

class LightVolume final : public LightTransmittance {
public:
    /// Texels per light at most (64 MiB): past it the lattice's spacing grows.
    static constexpr uint64_t kMostTexels = uint64_t(1) << 24;

    /// `spacing`: texel spacing in world units (at a point light's farthest reach for its pyramids);
    /// `extinction_scale`: the field's extinction is multiplied by it (an octave of multiple scattering).
    LightVolume(const Light& light, const ExtinctionField& field, const Vec3& origin, double spacing, RenderControl& control,
                float extinction_scale = 1.0f);

    float8 at(const Vec3x8& position) const override;
    float at(const Vec3f& position) const override;
    uint64_t texels() const { return transmittance_.size() - 1; }

private:
    /// One lattice: a sun's box, or one pyramid of a point light (axis, sign).
    struct Face {
        bool used = false;
        int axis = 2;
        float sign = 1;
        float u0 = 0, du = 1, v0 = 0, dv = 1, w0 = 0, dw = 1;
        int nu = 2, nv = 2, nw = 2;
        size_t offset = 0;  // into transmittance_, layout [v][w][u]
        uint64_t texels() const { return uint64_t(nu) * nv * nw; }
    };
    /// Lays the faces out at texel spacing h over the field's corners; returns the texels they take.
    uint64_t lay_out(const std::vector<Vec3>& corners, double h);
    /// A texel's position (relative to the origin) for lanes u, v of face f at w.
    Vec3x8 position(const Face& f, float8 u, float8 v, float w) const;
    /// Integrates face f's columns.
    void integrate(const Face& f, const ExtinctionField& field, RenderControl& control);
    /// The transmittance at eight points of face f (coordinates u, v, w in its parameters).
    float8 transmittance(const Face& f, float8 u, float8 v, float8 w) const;

    bool point_;
    float extinction_scale_;
    float spread_ = 0;     // sun: tan(angle / 2), > 0: soft shadows (penumbra.h)
    // Soft shadows only, while the lattice is built: each texel's optical depth and its occluders' mean w.
    std::vector<float> depth_, occluder_;
    Vec3f pivot_;          // point: the light's position; sun: unused
    Vec3f frame_[3];       // sun: unit rows e1, e2 and the direction of travel
    std::vector<Face> faces_;  // sun: one; point: six, 2 axis + (sign < 0)
    /// Each texel's transmittance times kWhole, rounded: 16 bits (to 1.5e-5), half the memory of floats, and
    /// a texel and its neighbour along u in one 32-bit read (four gathers a lookup instead of eight).
    static constexpr float kWhole = 65535.0f;
    std::vector<uint16_t> transmittance_;
};

/// The light volumes of a render: one per light that casts shadows (Light::casts_shadow), and with
/// `ambient_occlusion` one per ambient_occlusion_suns direction, at twice the texel spacing (the ambient
/// term is the mean of six: a texel's error weighs a sixth, and the lattices cost an eighth).
/// With `octaves` > 1 (multiple scattering), octaves 1 to octaves - 1 get the same again at the extinction
/// scaled by OctaveFactors::extinction^k, at twice the spacing (their light has scattered: its shadows are soft).
class LightVolumes {
public:
    LightVolumes(const std::vector<ShadedVolume>& volumes, const Lighting& lighting, bool render_shadows, bool ambient_occlusion,
                 const Kernel& kernel, const Vec3& origin, RenderControl& control, int octaves = 1);
    ~LightVolumes();
    /// For Shader: empty when no light casts shadows, else one per light (null: no shadow).
    const std::vector<const LightTransmittance*>& per_light() const { return per_light_; }
    /// For Shader: the ambient occlusion directions' (empty without).
    const std::vector<const LightTransmittance*>& occluders() const { return occluders_; }
    /// For Shader: octaves 1, 2, ... of multiple scattering (empty without).
    const std::vector<ScatteringOctave>& octaves() const { return octaves_; }
    uint64_t texels() const;

private:
    std::vector<std::unique_ptr<LightVolume>> volumes_;
    std::vector<const LightTransmittance*> per_light_, occluders_;
    std::vector<ScatteringOctave> octaves_;
};

/// The octaves of multiple scattering a render needs: the most any volume's material asks for (1: none), 1
/// where no light casts shadows and there is no ambient occlusion (nothing to scatter into the shade).
int scattering_octaves(const std::vector<ShadedVolume>& volumes, const Lighting& lighting, bool render_shadows);

}  // namespace pcvr
