/// @file cut_splat.h
/// @brief The voxels whose kernels a clip plane cuts, integrated along each pixel's own ray.
///
/// A footprint is the line integral of a whole kernel; a kernel that a clip plane (or a crop box's
/// face) passes through keeps only the part of each ray on the kept side, and that part changes across
/// the footprint. Where a plane is seen edge-on the kept image has a sharp edge, which no subgrid and
/// post-convolution can carry, so these voxels are not splatted into the subgrid: each pixel whose ray
/// meets the kernel gets value x P(rho, kept interval) directly, from Kernel::segment_integral (the
/// exact reference does the same for every voxel). They are a shell one kernel diameter thick along
/// the cuts, so the cost follows the cut's area, not the volume.
/// The voxels of a block that straddles a cut are sorted by split_cut_block: wholly kept ones go on
/// to the ordinary splats, cut ones here, wholly removed ones nowhere.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/clip_region.h"
#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "pcvr/lanes.h"
#include "pcvr/render_control.h"
#include "splat/post_convolution.h"
#include "splat/splat_grid.h"
#include "view/view_projection.h"

namespace pcvr {

/// A voxel whose kernel a cut crosses: its index-space centre and value (times its density scale).
struct CutVoxel {
    Vec3 centre;
    double amplitude;
};

/// The kept part of a kernel's line integral by tables. A Gaussian separates along a line:
/// h(sqrt(rho^2 + s^2)) = h(rho) h(s) / h(0), so the part of the chord (half-length sqrt(R^2 - rho^2))
/// from s0 to s1 is h(rho) (G(s1) - G(s0)) with G(s) the integral of h from 0 to s over h(0): two
/// interpolated tables and a square root instead of two erf and an exp. Other kernels take
/// Kernel::segment_integral.
class CutProfile {
public:
    explicit CutProfile(const Kernel& kernel);
    double radius() const { return radius_; }

    double operator()(double rho2, double s0, double s1) const {
        if (!separable_) return kernel_.segment_integral(std::sqrt(rho2), s0, s1);
        const double half = std::sqrt(std::max(radius_ * radius_ - rho2, 0.0));
        s0 = std::clamp(s0, -half, half), s1 = std::clamp(s1, -half, half);
        if (!(s1 > s0)) return 0.0;
        return lerp(centre_, rho2 * rho2_scale_) * (lerp(along_, (s1 + radius_) * s_scale_) - lerp(along_, (s0 + radius_) * s_scale_));
    }
    /// Eight at once, in float (Gaussians only): s0 and s1 already within the chord.
    bool separable() const { return separable_; }
    float8 operator()(float8 rho2, float8 s0, float8 s1) const {
        return lerp8(centre8_.data(), rho2 * float(rho2_scale_)) *
               (lerp8(along8_.data(), (s1 + float(radius_)) * float(s_scale_)) - lerp8(along8_.data(), (s0 + float(radius_)) * float(s_scale_)));
    }

private:
    static float8 lerp8(const float* table, float8 x) {
        x = clamp8(x, 0.0f, float(kEntries));
        const int8x i = __builtin_convertvector(x, int8x);
        return lerp_pairs8(table, i, x - __builtin_convertvector(i, float8));
    }
    static constexpr int kEntries = 4096;
    static double lerp(const std::vector<double>& table, double x) {
        x = std::clamp(x, 0.0, double(kEntries));
        const int i = int(x);
        return table[i] + (x - i) * (table[i + 1] - table[i]);
    }

    const Kernel& kernel_;
    double radius_;
    bool separable_;
    double rho2_scale_ = 0, s_scale_ = 0;
    std::vector<double> centre_, along_;  // h(sqrt(rho^2)); G(s) from -R to R
    std::vector<float> centre8_, along8_;  // the same in float, for gathers
};

/// `block` with only the voxels whose kernels (of `radius`) lie wholly inside `clip` (index space)
/// active; the non-zero ones that straddle it are appended to `cut`.
VoxelBlock split_cut_block(const VoxelBlock& block, const ClipRegion& clip, double radius, double density_scale,
                           std::vector<CutVoxel>& cut);

/// A cut seen within 30 degrees of face-on (the cosine between the plane's normal and the view, in index
/// space) leaves a kernel's kept footprint nearly as smooth as the footprint itself: its node values,
/// post-convolved like every other voxel's, keep the kernel's kept integral within 0.7% (one voxel cut
/// anywhere at 2 to 8 pixels per voxel; 2.3% at 45 degrees, 10% at 60, measured). Those voxels go into
/// the subgrid; cuts seen more nearly edge-on, whose kept footprints have sharp edges, per pixel.
constexpr double kSmoothCut = 0.866;

/// A worker's memory for CutSplatter (the planes near a voxel, one row's terms), reused voxel after
/// voxel: thread_local in a loaded module costs a call per access.
struct CutScratch {
    struct Row;
    CutScratch();
    ~CutScratch();
    std::unique_ptr<Row> row;
    std::vector<size_t> near;
};

/// The cut voxels of one grid in one view. Pixel rays are affine in the pixel's coordinates, in origin
/// and direction (orthographic rays share their direction, perspective ones their origin), so what a
/// tap needs (where the ray passes the voxel, where it crosses each plane) is a polynomial of degree two
/// at most in them: set up once per view, per voxel and per row, evaluated per tap by Horner.
/// Thread-safe: one per view, shared by the workers.
class CutSplatter {
public:
    /// `clip` in the grid's index space, as `view`.
    CutSplatter(const ViewProjection& view, const ClipRegion& clip, const Kernel& kernel);

    /// True when every plane that crosses the voxel's kernel is seen within kSmoothCut of face-on (or,
    /// orthographic, exactly edge-on: see masks()).
    bool smooth(const CutVoxel& voxel) const;
    /// Orthographic views of planes seen exactly edge-on: every ray runs along such a plane, wholly kept
    /// or wholly cut, so a kernel it crosses keeps its whole footprint on the kept side of the plane's
    /// line in the image and none beyond. Those planes are left out of the integrals (the footprints stay
    /// smooth, and go into the subgrid), and the grid's image is multiplied by mask(): the edge is then
    /// exact at every pixel, and costs nothing per voxel.
    bool masks() const;
    /// Zeroes the pixels whose rays lie beyond a plane seen edge-on.
    void mask(ImageAccumulator& image) const;
    /// The clip region less the planes seen edge-on: what the splats of a masked grid cut by.
    ClipRegion unmasked() const;
    /// Adds the voxel's kept line integral at every node of `grid` whose ray meets its kernel (a smooth
    /// cut, or a grid whose nodes are the pixels). Returns the taps evaluated.
    uint64_t splat(const CutVoxel& voxel, SplatGrid& grid, CutScratch& scratch) const;
    /// Adds each voxel's kept line integral to every pixel of `image` whose ray meets its kernel, in
    /// parallel. Returns the taps evaluated.
    uint64_t splat(const std::vector<CutVoxel>& voxels, ImageAccumulator& image, RenderControl& control) const;

    /// c00 + c10 x + c01 y + c20 x^2 + c11 x y + c02 y^2, and the same of degree one.
    struct Quadratic2 {
        double c00 = 0, c10 = 0, c01 = 0, c20 = 0, c11 = 0, c02 = 0;
    };
    struct Linear2 {
        double c0 = 0, cx = 0, cy = 0;
    };
    /// Where a voxel's kept integrals go: the points x = scale (column + first_column), y = scale (row +
    /// first_row) in pixel coordinates (the image's pixels, or a subgrid's nodes).
    struct Lattice {
        double scale;
        int first_column, first_row, columns, rows;
    };

private:
    template <class RowOf>
    uint64_t add(const CutVoxel& voxel, const Lattice& at, CutScratch& scratch, RowOf&& out) const;
    /// Gaussians: eight taps at a time in float, every term a polynomial about the kernel's first lattice
    /// point; other kernels (and kernels near more than eight planes) row by row in double.
    template <class RowOf>
    uint64_t add_lanes(const CutVoxel& voxel, const Lattice& at, CutScratch& scratch, RowOf&& out) const;
    template <class RowOf>
    uint64_t add_rows(const CutVoxel& voxel, const Lattice& at, CutScratch& scratch, RowOf&& out) const;

    const ViewProjection& view_;
    const ClipRegion& clip_;
    CutProfile profile_;
    Vec3 o0_, ox_, oy_, d0_, dx_, dy_;  // pixel rays in index space: origin and direction, affine in (x, y)
    bool parallel_;                     // orthographic: every ray has the same direction
    Quadratic2 dd_, world_;             // D.D, and W.W (W the world direction)
    double pixel_x0_ = 0, pixel_y0_ = 0, reach_x_ = 0, reach_y_ = 0;  // orthographic: pixel = p0 + gradient . index
    Vec3 pixel_x_, pixel_y_;
    std::vector<Linear2> plane_value_, plane_rate_;  // per plane, n.o + d and n.D
    std::vector<char> edge_on_;                     // per plane: seen exactly edge-on (orthographic)
};

}  // namespace pcvr
