/// @file brick_order.h
/// @brief A grid cut into bricks (cubes of index space) for renders that cannot hold it whole, and the
/// order in which a camera sees them.
///
/// Shaded and MIP images are not sums: each pixel composites its ray's samples front to back. A grid too
/// big for memory renders brick by brick, each brick read with a margin of voxels that the kernels, the
/// post filter and the gradients reach across its faces, and owning the samples in its own box
/// (shaded/sheets/sample_ownership.h). Bricks of a rectilinear partition have a visibility order from any
/// eye (the slab order): a ray runs monotonically along each axis away from the eye, so a brick that
/// occludes another lies, along every axis, between the eye's brick and the other one; the sum over the
/// axes of the cell distance from the eye's brick (an orthographic camera: the cell index signed by the
/// view direction) is then smaller for it. Sorting by that sum orders every ray at once.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

#include "pcvr/camera.h"
#include "pcvr/math.h"

namespace pcvr {

/// A half-open box of index space [lo, hi), bounds infinite where a brick is open to that side.
struct IndexBox {
    std::array<double, 3> lo{-INFINITY, -INFINITY, -INFINITY}, hi{INFINITY, INFINITY, INFINITY};
};

struct Brick {
    std::array<int64_t, 3> cell;     ///< its place in the partition
    std::array<int32_t, 6> read_box; ///< the voxels it reads: its own and the margin's (inclusive)
    IndexBox owned;                  ///< the samples it renders (outer bricks open towards the outside)
    uint64_t bytes = 0;              ///< values read: whole leaves and tiles' voxels that meet read_box
};

/// A brick's voxels along each index axis.
using BrickSides = std::array<int, 3>;

/// The bricks (boxes of `side` voxels at multiples of `side`, the outer ones open outwards) over the
/// values in `value_boxes` (inclusive index boxes, GridStream::value_boxes), each with `margin` voxels
/// more on every side to read; only those that read some value.
std::vector<Brick> cut_into_bricks(const std::vector<std::array<int32_t, 6>>& value_boxes, const BrickSides& side, int margin);

/// Sides at which every brick `fits(sides, bytes)`, `bytes` being the most values one reads: the largest
/// power-of-two cube (16 to 4096), then each axis grown in steps of 16 up to twice that while all still
/// fit; zeros where even cubes of 16 do not.
BrickSides brick_sides(const std::vector<std::array<int32_t, 6>>& value_boxes, int margin,
                       const std::function<bool(const BrickSides& sides, uint64_t bytes)>& fits);

/// Indices into `bricks` (cut_into_bricks at `side`) front to back as `camera` sees the grid with this
/// index-to-world transform: every ray meets them in this order (ties: no ray meets both).
std::vector<size_t> visibility_order(const std::vector<Brick>& bricks, const BrickSides& side, const Camera& camera,
                                     const Mat4& index_to_world);

}  // namespace pcvr
