/// @file sheet_sampling.h
/// @brief Sheets filled by sampling the volume instead of splatting it, where that costs less.
///
/// A splat costs its footprint's taps on every sheet its kernel reaches, whether or not the pixels it
/// lands on will ever be seen; at low magnification (a footprint of a few pixels, no post-convolution)
/// the walk's sheets can be filled the other way round: each pixel that may be seen takes its value from
/// the volume, as a ray caster would, and only there. The value is the kernel's reconstruction, as the
/// splats' sum would give it: trilinear interpolation of the grid's PrefilteredLattice, whose blur makes
/// up most of the kernel's variance less the tent's (1/6 per axis), integrated over the slab along the ray
/// (sheets hold slab integrals in the sheet parameter). Which pixels: the tile's blocks left after
/// culling whose kernels reach the sheet mark the 8 x 8 cells they reach; of those, vectors of eight
/// pixels that only opaque pixels read are left out, and so are those where nothing within the
/// reach of the samples that read them may be visible (the lattice's brick ranges): they keep 0, as
/// where no block reaches.
#pragma once

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "pcvr/lanes.h"
#include "pcvr/math.h"
#include "pcvr/transfer_function.h"
#include "shaded/sheets/sheet_geometry.h"
#include "splat/post_convolution.h"
#include "volume/brick_visibility.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace pcvr {

/// The blur weight w (PrefilteredLattice) sampled sheets use for `kernel`: three quarters of the one under
/// which trilinear interpolation would have the kernel's per-axis variance (measured nearest the ray
/// caster), or a negative number for kernels that are not smooth enough to stand in for (the box, the
/// linear kernel: narrower than the tent itself).
float lattice_blur(const Kernel& kernel);

struct SheetSampler {
    const PrefilteredLattice* lattice = nullptr;
    Vec3 origin;        ///< lattice coordinates of SheetGeometry::origin0
    Mat4 to_index;      ///< world to index coordinates (its linear part: to lattice displacements)
    /// SheetGeometry's origin_dx, origin_dy, dir0, dir_dx and dir_dy as lattice displacements: a row's
    /// rays from a few multiply-adds instead of five transforms per run of vectors.
    Vec3 origin_dx, origin_dy, dir0, dir_dx, dir_dy;
    float density_scale = 1;
    double block_span = 0;  ///< sheet parameter from a block's front (SlabView::front) past which its kernels end
    /// What decides which values may be visible (null: every one is sampled), and the density the
    /// sheets' values are added to (WalkGrid::background); the in-sheet gradient's step in pixels.
    const ClassificationTable* classification = nullptr;
    float background = 0;
    int gradient_step = 1;
    /// Whether this sampler made its brick visibility bits (false: the lattice had them for this transfer function).
    bool visibility_built = false;

    SheetSampler() = default;
    SheetSampler(const PrefilteredLattice& lattice, const Mat4& index_to_world, const SheetGeometry& geometry, float density_scale,
                 double block_span, const ClassificationTable* classification, float background, int gradient_step,
                 PostFilterShape post_shape);

    /// The largest post-convolution stride sampled sheets take.
    static constexpr int kMostStride = 4;

    /// The subgrid stride of the sheet of parameter u: the whole pixels a lattice element spans at the
    /// image's centre (as automatic_stride, one node per element), capped at kMostStride. Above 1 the
    /// sheet is sampled at its subgrid nodes and post-convolved to the pixels, as the paper's subgrid
    /// is splatted; the same for every tile, so that tiles meet without seams.
    int stride_at(const SheetGeometry& geometry, bool spherical, double u, int width, int height) const;
    /// The post filter from a stride-L subgrid to the pixels.
    const PostFilter& post_filter(int stride) const { return post_filters_[size_t(stride - 1)]; }

    /// The brick bits that tell which values of the sheet of parameter u at pixels [x0, x1] x [y0, y1] no
    /// sample that may be visible reads, or null where the lattice's ranges cannot tell (or the grid is not
    /// classified): those of the tightest range set (PrefilteredLattice::kTightRangeReach, kRangeReach) within
    /// whose reach lies what such a value reaches, `spread` pixels of post-convolution included.
    const BrickVisibilityCache::Bits* skip_bits(const SheetGeometry& geometry, bool spherical, double u, float spacing, int x0, int y0,
                                                int x1, int y1, int spread = 0) const;

    /// Slab integrals of the volume on the sheet of parameter u (its middle) and thickness `spacing`
    /// at pixels x0, x0 + step, ... (8 n of them) of row y, added to out[0 .. width) (width <= 8 n: the
    /// values past it are left out); with `skip` (skip_bits), nothing for vectors that nothing visible
    /// reads. Returns how many vectors were interpolated.
    int sample_run(const SheetGeometry& geometry, bool spherical, double u, float spacing, int x0, int y, int n,
                   const BrickVisibilityCache::Bits* skip, float* out, int width, int step = 1) const;

private:
    /// World displacements as lattice (index) displacements, eight at a time.
    Vec3x8 in_index(const Vec3x8& v) const;
    /// One bit per lattice brick (PrefilteredLattice::bricks, bk fastest), set where its range, 0 included,
    /// may be visible under `classification`: decided once per visible span and kept with the lattice
    /// (BrickVisibilityCache), so the per-vector test is a lookup in a table small enough to stay in cache
    /// (a bit a brick: 118 KB for the CT head, where the ranges are 1.9 MB). Null without a classification.
    /// One per range set: PrefilteredLattice::ranges and tight_ranges.
    std::shared_ptr<const BrickVisibilityCache::Bits> visible_bricks_, tight_visible_bricks_;
    std::vector<PostFilter> post_filters_;  // strides 1 .. kMostStride
};

}  // namespace pcvr
