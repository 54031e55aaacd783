/// @file raycast_reference.h
/// @brief The reference for shaded rendering and MIP: each pixel's ray marched in fine steps through the
/// same reconstruction, transfer function, gradient and lighting, with no tables, sheets or culling.
///
/// Plain and slow on purpose, so that tests can trust it. A pixel's ray is sampled at the depths
/// near + (k + 1/2) step, step = sheet_spacing voxels along the view axis (give it a fine one), inside
/// the grids' bounding boxes widened by the kernel radius. At a sample the density is the sum over
/// every active voxel within the radius of v h(|B x - i|) in double (B: world to index), and its
/// gradient the analytic sum of the kernels' gradients. Classification (with the sample's ray length
/// as its thickness), lighting, the mixing of overlapping grids and front-to-back compositing are
/// those of the sheet renderer; a sample where no voxel reaches (density exactly 0) is empty, and a
/// ray stops once its opacity passes opacity_cutoff. MIP keeps the largest non-zero sample.
/// With shadows (ShadedParams::shadows, Light::shadow), each lit sample marches a shadow ray towards each
/// shadowed light through the same reconstruction, classified and clipped per grid, in steps of
/// sheet_spacing voxels of the finest grid, and the light is multiplied by exp(-its optical depth).
/// `pixel_step` > 1 renders every step-th pixel of each row and column.
#pragma once

#include <vector>

#include "pcvr/camera.h"
#include "pcvr/render_control.h"
#include "pcvr/shaded.h"
#include "pcvr/shading.h"

namespace pcvr {

/// Premultiplied RGBA, 4 floats per pixel, into `rgba` (ceil(h / step) x ceil(w / step) pixels); and,
/// when `depth` is given, the depth of the sample at which opacity first reached one half.
void raycast_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                    const ShadedParams& params, RenderControl& control, float* rgba, float* depth = nullptr);

/// The largest density along each ray, one float per pixel, into `out`.
void raycast_mip(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params,
                 RenderControl& control, float* out);

}  // namespace pcvr
