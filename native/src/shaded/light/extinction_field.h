/// @file extinction_field.h
/// @brief The extinction coefficient of all the volumes of a render at any point, eight points at a time:
/// what the lights' transmittance volumes (light_volume.h) integrate.
///
/// Each grid is resampled once into a dense lattice at its voxel centres: the kernel's reconstruction
/// there (the sum over the voxels within its radius of (value - background) h(|offset|), the exact value
/// the splats and the ray caster reconstruct at those points), and trilinear in between. A point's
/// density is the background plus that departure, times the grid's density scale, classified through
/// its transfer function (post-classification, as the samples are); where the departure is exactly 0
/// no voxel reaches, and the point is empty whatever the transfer function says (as in the sheets).
/// Each grid's clip region removes its extinction outside; extinctions of overlapping grids add up.
/// Gradient opacity is not applied: shadow casters stop light by their density alone.
///
/// Against the kernel everywhere (the ray caster's shadow rays), trilinear interpolation between the
/// voxel centres differs inside a voxel by up to the field's curvature times an eighth of a voxel
/// squared: tests/native/test_shadows.py measures what that does to the images.
///
/// A grid whose padded bounding box holds more than kMostVoxels voxels is resampled from its coarsest
/// level of detail that fits (Grid::level, means over the background), so memory stays bounded.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/kernel.h"
#include "pcvr/lanes.h"
#include "pcvr/shaded.h"
#include "pcvr/transfer_function.h"
#include "shaded/classify/sample_clip.h"

namespace pcvr {

class ExtinctionField {
public:
    static constexpr uint64_t kMostVoxels = uint64_t(1) << 26;  // 256 MiB of floats per grid

    /// Positions passed to at() are relative to `origin` (world), as the shaders' are.
    ExtinctionField(const std::vector<ShadedVolume>& volumes, const Kernel& kernel, const Vec3& origin);
    ~ExtinctionField();

    /// Extinction per world unit at eight points.
    float8 at(const Vec3x8& position) const;
    /// The extinction and the transfer functions' colour (weighted by the grids' extinctions; 0 where none) at
    /// eight points: the medium the path tracer scatters in (src/shaded/reference/path_tracer.h).
    struct Medium {
        float8 extinction;
        Vec3x8 albedo;
    };
    Medium medium(const Vec3x8& position) const;
    /// The corners (relative to the origin) of each grid's box, widened by the kernel's reach: no
    /// extinction outside them.
    const std::vector<Vec3>& corners() const { return corners_; }
    /// The smallest voxel spacing of the grids (world units).
    double smallest_spacing() const { return smallest_spacing_; }
    bool empty() const { return lattices_.empty(); }

private:
    struct Lattice;
    /// Calls fn(table, density, reached) for each grid's lattice that the points may reach.
    template <class Fn>
    void densities(const Vec3x8& position, Fn&& fn) const;
    std::vector<std::unique_ptr<Lattice>> lattices_;
    std::vector<Vec3> corners_;
    double smallest_spacing_ = INFINITY;
};

}  // namespace pcvr
