/// @file path_tracer.h
/// @brief The brute-force reference for multiple scattering: Monte Carlo path tracing through the volumes'
/// extinction, slow and simple, which judges the octaves of src/shaded/light (Shading::scattering_octaves).
///
/// | step              | how                                                                          |
/// |-------------------|------------------------------------------------------------------------------|
/// | medium            | ExtinctionField: each grid's kernel reconstruction at its voxel centres, trilinear between, classified by its transfer function (the field the light volumes integrate); albedo: the transfer functions' colours, weighted by extinction |
/// | free flight       | regular tracking: the optical depth summed at midpoints `sheet_spacing` of the finest voxel apart until it reaches -ln(1 - u) |
/// | at a vertex       | the throughput times the albedo; each light by next-event estimation (its transmittance marched the same way, phase function times its energy); then a direction drawn from the Henyey-Greenstein phase function (weight 1) |
/// | leaving the boxes | a scattered path gathers the ambient colour (the world's light, always occluded); a camera ray that never scattered gathers nothing (alpha is 1 - its transmittance) |
/// | termination       | Russian roulette after kRouletteAfter vertices, at most kMostVertices       |
///
/// Every light casts shadows here (light that scatters many times needs them); emission, albedo grids, gradient
/// opacity and Blinn-Phong materials are not modelled, and the anisotropy is the first volume's material's.
/// Pixel centres; each pixel's random numbers come from `seed` and its index alone (splitmix64), so images do
/// not depend on the thread count. The error falls as 1 / sqrt(paths).
#pragma once

#include <vector>

#include "pcvr/camera.h"
#include "pcvr/render_control.h"
#include "pcvr/shaded.h"
#include "pcvr/shading.h"

namespace pcvr {

/// Premultiplied RGBA, 4 floats per pixel, into `rgba` (ceil(h / step) x ceil(w / step) pixels, ShadedParams::
/// pixel_step), ShadedParams::paths paths per pixel.
void path_trace_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                       const ShadedParams& params, RenderControl& control, float* rgba);

}  // namespace pcvr
