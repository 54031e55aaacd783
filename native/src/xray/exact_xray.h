/// @file exact_xray.h
/// @brief The reference X-ray: each voxel's analytic line integral evaluated per pixel in double.
///
/// Independent of the splatting path on purpose: no footprint table, no linearised ellipse, no
/// subgrid. Each pixel's own ray (from the camera's inverse matrix) is intersected with each voxel's
/// kernel sphere, and Kernel::line_integral gives the contribution (Kernel::segment_integral over the
/// ray's interval inside the grid's clip region where a cut crosses the kernel). It is slow (O(voxels x footprint
/// pixels) with special functions) and meant for tests and error measurements; `pixel_step` > 1
/// evaluates only pixels (step * i, step * j) to make large comparisons affordable.
#pragma once

#include <vector>

#include "pcvr/camera.h"
#include "pcvr/kernel.h"
#include "pcvr/render_control.h"
#include "pcvr/xray.h"

namespace pcvr {

/// Returns a ceil(height / step) x ceil(width / step) row-major image.
std::vector<double> render_exact_xray(const std::vector<WeightedGrid>& grids, const Camera& camera,
                                      const Kernel& kernel, int pixel_step, RenderControl& control);

}  // namespace pcvr
