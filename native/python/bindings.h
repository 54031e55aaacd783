// Shared declarations of the thin nanobind layer: one file per part of the API.
#pragma once

#include <nanobind/nanobind.h>

#include "pcvr/math.h"

namespace pcvr::python {

void bind_grid(nanobind::module_& m);    // bind_grid.cpp: Grid, read_vdb, list_grids
void bind_render(nanobind::module_& m);  // bind_render.cpp: Camera, render_xray, kernel_info
void bind_shaded(nanobind::module_& m);  // bind_shaded.cpp: TransferFunction, Light, Shading, render_shaded, render_mip

/// A (4, 4) array-like (numpy array, nested sequence, mathutils.Matrix) -> Mat4. Raises ValueError
/// naming `what` when the shape is wrong or a value is not finite.
Mat4 mat4_from_python(nanobind::handle obj, const char* what);
/// Mat4 -> new (4, 4) float64 numpy array.
nanobind::object mat4_to_numpy(const Mat4& m);

}  // namespace pcvr::python
