/// @file block_linearisation.h
/// @brief A perspective view's footprints across one voxel block, as functions of the voxel's offset.
///
/// Under perspective every voxel has its own footprint, and computing it (ViewProjection::
/// footprint_lanes, in double) cost as much as splatting it: half of a perspective X-ray's time.
/// Across an 8^3 block the footprint's form and line scale change smoothly, to first order in the
/// voxel's offset d from the block's origin, with a remainder of about (4 / D)^2 of their size at
/// D voxels from the eye. So a block's exact footprints at its centre and at its eight corners fix
/// an affine model of each, and the voxels take theirs from it in float, eight at a time; their
/// centres stay exact, since a projection is a ratio of affine functions. Blocks where the model
/// misses a corner's exact footprint by more than kLinearisedTolerance (near the eye), that reach
/// beyond a clip plane, or whose narrower-than-a-pixel footprints are tilted enough to be widened
/// (pixel_prefilter.h), keep the exact per-voxel projection.
///
/// Whether a block's footprints are integrated over pixels is the block's choice, made at its centre
/// (block_prefiltered, view/footprint_limits.h), not each voxel's: a block that holds footprints both a little wider and a little
/// narrower than a pixel (every block of a view at about one pixel per voxel) then takes one table for
/// all of them, where voxel by voxel it cost 1.6-2.2 times the orthographic splat (issue 37). Either
/// treatment is right there (at one pixel per voxel sampled and pixel-averaged footprints differ by 0.2%
/// on smooth volumes, pixel_prefilter.h), and the choice depends on the view and the block alone, so a
/// stream's batches choose as the grid read whole does.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "pcvr/grid.h"
#include "splat/pixel_prefilter.h"
#include "splat/splat_grid.h"
#include "view/view_projection.h"

namespace pcvr {

/// The model's largest error at a corner, relative to the form's mean eigenvalue (and to the line
/// scale): 1e-3 moves a footprint's weights by at most 6e-4 of its peak (1.4 rho^2 x 1e-3 at
/// the kernel's rim, where the weight is 1/270 of the peak, and less inside), half of what the
/// footprint table's own quantisation does (1.3e-3).
constexpr double kLinearisedTolerance = 1e-3;

/// f(d) = at + slope . d for d the voxel's index offset from the block's origin, as floats.
struct AffineInBlock {
    float at = 0, di = 0, dj = 0, dk = 0;
};

struct BlockLinearisation {
    /// Node coordinates (relative to the caller's reference node) are x / w and y / w.
    AffineInBlock x, y, w;
    /// The footprint's form in node^2 units of the target grid, and its line scale.
    AffineInBlock qxx, qxy, qyy, line_scale;
    /// Every footprint of the block is narrower than a pixel and integrated over pixels along the
    /// pixel axes (none is tilted enough to be widened).
    bool prefiltered = false;
};

namespace detail {

/// The affine function of d through `centre` (its value at d = 3.5^3) with the corners' mean slope:
/// corners[c] is the value at d = 7 (c & 1, c & 2, c & 4). nullopt when it misses a corner by more than `tolerance`.
inline std::optional<AffineInBlock> fit_corners(double centre, const std::array<double, 8>& corners, double tolerance) {
    double slope[3] = {0, 0, 0};
    for (int c = 0; c < 8; ++c)
        for (int axis = 0; axis < 3; ++axis) slope[axis] += ((c >> axis) & 1 ? corners[c] : -corners[c]) / (4.0 * 7.0);
    const double at = centre - 3.5 * (slope[0] + slope[1] + slope[2]);
    for (int c = 0; c < 8; ++c) {
        const double model = at + 7.0 * ((c & 1) * slope[0] + ((c >> 1) & 1) * slope[1] + ((c >> 2) & 1) * slope[2]);
        if (!(std::abs(model - corners[c]) <= tolerance)) return std::nullopt;
    }
    return AffineInBlock{float(at), float(slope[0]), float(slope[1]), float(slope[2])};
}

}  // namespace detail

/// The linearisation of `block`'s footprints on a subgrid of nodes `stride` pixels apart, node
/// coordinates pixel / stride - (node_x0, node_y0); nullopt where the exact per-voxel projection is
/// needed (see above). `antialias`: footprints narrower than a pixel are prefiltered, with the
/// kernel's `kernel_variance` (index units^2).
inline std::optional<BlockLinearisation> linearise_block(const VoxelBlock& block, const ViewProjection& view, double stride,
                                                         double node_x0, double node_y0, bool antialias,
                                                         double kernel_variance) {
    const Vec3 origin{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])};
    const double stride2 = stride * stride;
    Footprint centre, corner[8];
    if (!view.footprint(origin + Vec3{3.5, 3.5, 3.5}, centre)) return std::nullopt;
    const bool narrow = antialias && prefiltered(centre);  // as block_prefiltered, from the same footprint
    for (int c = 0; c < 8; ++c) {
        const Vec3 offset{7.0 * (c & 1), 7.0 * ((c >> 1) & 1), 7.0 * ((c >> 2) & 1)};
        Footprint& f = corner[c];
        if (!view.footprint(origin + offset, f)) return std::nullopt;
        if (narrow && FootprintCovariance(f.qxx * stride2, f.qxy * stride2, f.qyy * stride2, kernel_variance).tilted(stride))
            return std::nullopt;
    }
    const double form_scale = 0.5 * (centre.qxx + centre.qyy) * stride2;
    auto fit = [&](auto member, double scale, double unit) -> std::optional<AffineInBlock> {
        std::array<double, 8> at_corners;
        for (int c = 0; c < 8; ++c) at_corners[c] = corner[c].*member * unit;
        return detail::fit_corners(centre.*member * unit, at_corners, kLinearisedTolerance * scale);
    };
    const auto qxx = fit(&Footprint::qxx, form_scale, stride2), qxy = fit(&Footprint::qxy, form_scale, stride2),
               qyy = fit(&Footprint::qyy, form_scale, stride2), line = fit(&Footprint::line_scale, centre.line_scale, 1.0);
    if (!qxx || !qxy || !qyy || !line) return std::nullopt;

    // node_x = a clip_x / clip_w + b: both parts affine in the index.
    const Camera& cam = view.camera();
    const Mat4& m = view.index_to_clip();
    const double ax = 0.5 * cam.width() / stride, bx = (0.5 * cam.width() - 0.5) / stride - node_x0;
    const double ay = -0.5 * cam.height() / stride, by = (0.5 * cam.height() - 0.5) / stride - node_y0;
    auto clip_row = [&](double a, int row, double b) {
        auto coeff = [&](int col) { return a * m.m[row][col] + b * m.m[3][col]; };
        const double at = coeff(0) * origin.x + coeff(1) * origin.y + coeff(2) * origin.z + coeff(3);
        return AffineInBlock{float(at), float(coeff(0)), float(coeff(1)), float(coeff(2))};
    };
    BlockLinearisation out;
    out.x = clip_row(ax, 0, bx);
    out.y = clip_row(ay, 1, by);
    out.w = clip_row(0.0, 3, 1.0);
    out.qxx = *qxx;
    out.qxy = *qxy;
    out.qyy = *qyy;
    out.line_scale = *line;
    out.prefiltered = narrow;
    return out;
}

/// The same on an X-ray's splat grid, node coordinates relative to node (ref_x, ref_y).
inline std::optional<BlockLinearisation> linearise_block(const VoxelBlock& block, const ViewProjection& view,
                                                         const SplatGrid& grid, int ref_x, int ref_y, bool antialias,
                                                         double kernel_variance) {
    return linearise_block(block, view, grid.stride(), grid.first_node_x() + ref_x, grid.first_node_y() + ref_y, antialias,
                           kernel_variance);
}

}  // namespace pcvr
