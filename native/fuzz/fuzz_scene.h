/// @file fuzz_scene.h
/// @brief What the fuzz targets share: small renders with bounded time and memory.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pcvr/camera.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/render_control.h"
#include "pcvr/xray.h"

namespace pcvr::fuzz {

/// Renders of more voxels than this take too long for a fuzzing iteration.
constexpr uint64_t kMaxRenderedVoxels = 20000;
/// Every render's buffers must fit this (MemoryBudget refuses the rest up front).
constexpr uint64_t kMemoryLimit = uint64_t(256) << 20;

inline XrayImage render(const Grid& grid, const Camera& camera, XrayParams params) {
    params.threads = 1;
    params.memory_limit = kMemoryLimit;
    RenderControl control;
    return render_xray({{&grid, 1.0}}, camera, params, control);
}

/// An orthographic 16 x 16 view down -Z of the grid's active bounding box, by every method.
inline void render_framed(const Grid& grid) {
    const auto b = grid.index_bbox();
    const Mat4& m = grid.index_to_world();
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p = m.transform_point({double(b[(corner & 1) ? 3 : 0]), double(b[(corner & 2) ? 4 : 1]),
                                          double(b[(corner & 4) ? 5 : 2])});
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    }
    const double half = 0.5 * std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-30}) * 1.5;
    Mat4 view;
    view.m[0][3] = -0.5 * (lo[0] + hi[0]);
    view.m[1][3] = -0.5 * (lo[1] + hi[1]);
    view.m[2][3] = -(hi[2] + half);
    Mat4 ortho;
    ortho.m[0][0] = ortho.m[1][1] = 1.0 / half;
    ortho.m[2][2] = -1.0 / (2.0 * half);
    ortho.m[2][3] = -1.0;
    try {
        const Camera camera(view, ortho, 16, 16);
        for (XrayMethod method : {XrayMethod::Exact, XrayMethod::Regular, XrayMethod::Pcvr, XrayMethod::BilinearSpread}) {
            XrayParams params;
            params.method = method;
            render(grid, camera, params);
        }
    } catch (const CameraError&) {
        // A box too large or too far out for a camera: nothing to render.
    }
}

}  // namespace pcvr::fuzz
