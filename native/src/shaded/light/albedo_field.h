/// @file albedo_field.h
/// @brief A volume's albedo per voxel: the colour of three grids on its voxels (Blender's Principled Volume
/// Color Attribute, Mantaflow's `color`), which multiplies the transfer function's colour at every sample
/// (ShadedVolume::albedo_grids).
///
/// At a point x the factor is the density-weighted colour of the eight lattice texels around it,
///
///     sum_j w_j d_j c_j / sum_j w_j d_j      (w_j trilinear, d_j the density's departure from its background, >= 0)
///
/// the colour of the density that is there: a sample mixes the voxels' media, each scattering in proportion
/// to its density, so voxels without density lend it no colour, and the edge of a coloured smoke keeps its
/// colour rather than fading towards the colour grid's zeros outside it. The lattice has a texel per voxel (at
/// most kMostTexels: past it texels are wider and sum the voxels nearest to them) over the density's active
/// box widened by two voxels, the kernel's reach. A texel without density takes its neighbours' colour, the
/// density-weighted sum over the 5^3 texels around it with tent weights, at a thousandth of their weight: where
/// density is near it hardly counts, and in the kernel's fringe, where the reconstruction still has a little
/// density but no voxel of the eight has any, the neighbours' colour is what there is. Beyond the lattice, or
/// where no density is near at all, the factor is the whole volume's density-weighted colour (1 without
/// density). The splatting renderers and the ray caster read the same factor at their samples' points (a
/// sample's colour is not integrated over its stretch of ray, as its density is); extinction is not changed.
/// Colours are taken as the grids hold them (an inactive voxel: its grid's background), not clamped.
///
/// Immutable after construction: safe to read from many threads.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/grid.h"
#include "pcvr/shaded.h"
#include "pcvr/shading.h"

namespace pcvr {

class AlbedoField final : public AlbedoModulation {
public:
    /// Texels at most (64 MiB of them, twice that while the lattice is built).
    static constexpr uint64_t kMostTexels = uint64_t(1) << 22;

    /// The field of `volume` (its grid and albedo grids), or null when it has no albedo grids. Positions
    /// passed to at() are relative to `origin` (world). Throws InvalidArgument when an albedo grid does not
    /// lie on the volume's voxels (another index_to_world).
    static std::unique_ptr<AlbedoField> of(const ShadedVolume& volume, const Vec3& origin);

    AlbedoField(const Grid& density, const std::array<const Grid*, 3>& colour, const Vec3& origin);

    Vec3x8 at(const Vec3x8& position) const override;
    Vec3f at(const Vec3f& position) const override;
    uint64_t texels() const { return texels_.size() / kChannels; }

private:
    /// A texel's floats: colour times density (red, green, blue), then the density.
    static constexpr int kChannels = 4;
    /// Sums each voxel with density into its nearest texel; returns the whole volume's sums (as a texel's).
    std::array<double, kChannels> fill(const Grid& density, const std::array<const Grid*, 3>& colour,
                                       const std::array<double, 3>& low, double spacing);
    /// Gives texels without density a thousandth of their neighbours' tent-weighted sums.
    void dilate();
    size_t index(int64_t x, int64_t y, int64_t z) const { return (size_t(x) * size_t(n_[1]) + size_t(y)) * size_t(n_[2]) + size_t(z); }

    Mat4 to_lattice_;  // positions relative to the origin -> lattice coordinates (texel (0, 0, 0) at 0)
    std::array<int64_t, 3> n_{0, 0, 0};
    std::vector<float> texels_;  // kChannels per texel, [x][y][z], z fastest
    Vec3f mean_{1, 1, 1};        // the density-weighted colour of every voxel
};

}  // namespace pcvr
