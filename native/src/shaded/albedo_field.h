/// @file albedo_field.h
/// @brief A volume's albedo per voxel: the colour of three grids on its voxels (Blender's Principled Volume
/// Color Attribute, Mantaflow's `color`), which multiplies the transfer function's colour at every sample
/// (ShadedVolume::albedo_grids).
///
/// At a point x the factor is the density-weighted colour of the eight voxels around it,
///
///     sum_j w_j d_j c_j / sum_j w_j d_j      (w_j trilinear, d_j the density's departure from its background, >= 0)
///
/// the colour of the density that is there: a sample mixes the voxels' media, each scattering in proportion
/// to its density, so voxels without density lend it no colour and the edge of a coloured smoke keeps its
/// colour rather than fading towards the colour grid's zeros outside it. Where none of the eight has density
/// (the kernel's fringe, up to two voxels beyond the last dense voxel), the same sum runs over the 4^3 voxels
/// of the kernel's reach with Gaussian weights exp(-|x - x_j|^2); where that finds no density either (the
/// post-filter and the samples between sheets spread a trace of density a little further), the factor is the
/// whole volume's density-weighted colour (1 without density). The splatting renderers and the ray caster read the same factor at their samples' points
/// (a sample's colour is not integrated over its stretch of ray, as its density is); extinction is not
/// changed. Colours are taken as the grids hold them (an inactive voxel: its grid's background), not clamped.
///
/// Voxels are found through a table of the grids' 8^3 blocks: dense over the blocks' bounding box (a
/// pointer per block), or hashed where that box would hold more than kMostDenseBlocks. Immutable after
/// construction: safe to read from many threads.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "pcvr/grid.h"
#include "pcvr/shaded.h"
#include "pcvr/shading.h"

namespace pcvr {

class AlbedoField final : public AlbedoModulation {
public:
    static constexpr uint64_t kMostDenseBlocks = uint64_t(1) << 22;

    /// The field of `volume` (its grid and albedo grids), or null when it has no albedo grids. Positions
    /// passed to at() are relative to `origin` (world). Throws InvalidArgument when an albedo grid does not
    /// lie on the volume's voxels (another index_to_world).
    static std::unique_ptr<AlbedoField> of(const ShadedVolume& volume, const Vec3& origin);

    AlbedoField(const Grid& density, const std::array<const Grid*, 3>& colour, const Vec3& origin);

    Vec3x8 at(const Vec3x8& position) const override;
    Vec3f at(const Vec3f& position) const override;

private:
    /// Voxel values by index through one grid's blocks.
    class Voxels {
    public:
        Voxels(const Grid& grid, const std::array<int64_t, 6>& block_box);
        /// Voxel (i, j, k)'s value, or the background where it is inactive or outside every block.
        float value(int64_t i, int64_t j, int64_t k) const;
        /// Voxel `offset` of a block (null: none there), or the background.
        float value(const VoxelBlock* block, int offset) const {
            return block && block->active(offset) ? block->value(offset) : background_;
        }
        /// The block at block coordinates (index >> 3), or null.
        const VoxelBlock* block(int64_t bi, int64_t bj, int64_t bk) const;

    private:
        float background_;
        std::array<int64_t, 6> box_;  // block coordinates (index >> 3): i0, j0, k0, i1, j1, k1 inclusive
        std::vector<const VoxelBlock*> dense_;
        std::unordered_map<uint64_t, const VoxelBlock*> hashed_;
    };

    /// Adds w d c (three sums) and w d over voxels lo..hi (inclusive, per axis) with weights weight(i, j, k).
    template <class Weight>
    void accumulate(const int64_t lo[3], const int64_t hi[3], Weight&& weight, double sum[4]) const;
    /// Adds density d and colour c to the sums (nothing where d is not positive and finite).
    static void add(double w, double d, const float colour[3], double sum[4]);
    /// The density-weighted colour of every voxel.
    Vec3f mean_colour(const Grid& density) const;

    Mat4 to_index_;  // from positions relative to the origin to the grids' index space
    float density_background_;
    std::vector<Voxels> voxels_;  // density, red, green, blue
    Vec3f mean_{1, 1, 1};         // the density-weighted colour of every voxel
};

}  // namespace pcvr
