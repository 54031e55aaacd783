#include "xray/exact_xray.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "pcvr/errors.h"
#include "view/view_projection.h"
#include "volume/block_voxels.h"

namespace pcvr {

namespace {

/// Each sampled pixel's ray in one grid's index space, with a unit direction.
struct IndexRays {
    std::vector<Vec3> origin, direction;
    std::vector<double> world_per_index;  // world length per index length along the ray
};

/// Camera space to index space directly (a grid and a camera far from the world's origin never meet
/// in world coordinates, where their offsets would cancel imprecisely).
IndexRays rays_in_index_space(const Camera& cam, const Mat4& camera_to_index, int step, int cols, int rows) {
    IndexRays rays;
    const size_t n = size_t(cols) * rows;
    rays.origin.resize(n);
    rays.direction.resize(n);
    rays.world_per_index.resize(n);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < cols; ++c) {
            const Ray ray = cam.camera_ray(double(c) * step, double(r) * step);
            const Vec3 d = camera_to_index.transform_vector(ray.direction);
            const double len = length(d);
            const size_t i = size_t(r) * cols + c;
            rays.origin[i] = camera_to_index.transform_point(ray.origin);
            rays.direction[i] = d / len;
            rays.world_per_index[i] = length(cam.camera_to_world().transform_vector(ray.direction)) / len;
        }
    return rays;
}

}  // namespace

std::vector<double> render_exact_xray(const std::vector<WeightedGrid>& grids, const Camera& cam, const Kernel& kernel,
                                      int pixel_step, RenderControl& control) {
    if (pixel_step < 1) throw InvalidArgument("pixel_step must be at least 1");
    const int cols = (cam.width() + pixel_step - 1) / pixel_step;
    const int rows = (cam.height() + pixel_step - 1) / pixel_step;
    const double radius = kernel.radius();
    std::vector<double> image(size_t(cols) * rows, 0.0);

    size_t total_blocks = 0;
    for (const auto& g : grids) total_blocks += g.grid->blocks().size();
    control.begin_phase(total_blocks, 0.0, 1.0);

    for (const auto& weighted : grids) {
        const Grid& grid = *weighted.grid;
        const Mat4& to_world = grid.index_to_world();
        const auto camera_to_index = (cam.world_to_camera() * to_world).inverse();
        if (!camera_to_index || !to_world.is_affine())
            throw GridError("grid '" + grid.name() + "': singular index-to-world transform");
        const IndexRays rays = rays_in_index_space(cam, *camera_to_index, pixel_step, cols, rows);
        // With a clip region, each ray's kept interval (unit index-space parameter from its origin).
        const ClipRegion clip = weighted.clip ? weighted.clip->in_index_space(to_world) : ClipRegion();
        std::vector<RayInterval> kept;
        if (!clip.keeps_everything())
            for (size_t i = 0; i < rays.origin.size(); ++i) kept.push_back(clip.ray_interval(rays.origin[i], rays.direction[i], -1e300, 1e300));
        const Mat4 to_clip = cam.object_to_clip(to_world);
        const auto& blocks = grid.blocks();

        tbb::enumerable_thread_specific<std::vector<double>> locals([&] { return std::vector<double>(image.size(), 0.0); });
        tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
            control.throw_if_cancelled();
            std::vector<double>& acc = locals.local();
            for (size_t b = range.begin(); b != range.end(); ++b) {
                const VoxelBlock& block = blocks[b];
                for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
                    if (!block.active(offset)) continue;
                    const double v = double(block.value(offset)) * weighted.density_scale;
                    if (v == 0.0 || !std::isfinite(v)) continue;
                    const Vec3 c = voxel_position(block, offset);
                    if (!ViewProjection::inside_clip_range(to_clip * Vec4{c.x, c.y, c.z, 1.0})) continue;
                    const ClipSide side = clip.sphere_side(c, radius);
                    if (side == ClipSide::Outside) continue;

                    // Pixels whose rays can meet the kernel sphere: inside the projection of its bounding cube.
                    int c0 = 0, c1 = cols - 1, r0 = 0, r1 = rows - 1;
                    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
                    bool bounded = true;
                    for (int k = 0; k < 8 && bounded; ++k) {
                        const Vec4 p = to_clip * Vec4{c.x + ((k & 1) ? radius : -radius), c.y + ((k & 2) ? radius : -radius),
                                                      c.z + ((k & 4) ? radius : -radius), 1.0};
                        if (!(p.w > 0)) bounded = false;
                        x0 = std::min(x0, cam.pixel_x(p.x / p.w));
                        x1 = std::max(x1, cam.pixel_x(p.x / p.w));
                        y0 = std::min(y0, cam.pixel_y(p.y / p.w));
                        y1 = std::max(y1, cam.pixel_y(p.y / p.w));
                    }
                    if (bounded) {
                        c0 = clamp_to_int(std::ceil(x0 / pixel_step), 0, cols);
                        c1 = clamp_to_int(std::floor(x1 / pixel_step), -1, cols - 1);
                        r0 = clamp_to_int(std::ceil(y0 / pixel_step), 0, rows);
                        r1 = clamp_to_int(std::floor(y1 / pixel_step), -1, rows - 1);
                    }
                    for (int r = r0; r <= r1; ++r)
                        for (int col = c0; col <= c1; ++col) {
                            const size_t i = size_t(r) * cols + col;
                            const Vec3 w = c - rays.origin[i];
                            const double closest = dot(w, rays.direction[i]);
                            const Vec3 perp = w - rays.direction[i] * closest;
                            const double rho2 = dot(perp, perp);
                            if (rho2 >= radius * radius) continue;
                            // A cut kernel keeps the part of the ray inside the region.
                            const double integral = side == ClipSide::Inside ? kernel.line_integral(std::sqrt(rho2))
                                                    : kept[i].empty()        ? 0.0
                                                                             : kernel.segment_integral(std::sqrt(rho2), kept[i].lo - closest, kept[i].hi - closest);
                            acc[i] += v * integral * rays.world_per_index[i];
                        }
                }
            }
            control.advance(range.size());
        });
        control.throw_if_cancelled();
        for (const auto& local : locals)
            for (size_t i = 0; i < image.size(); ++i) image[i] += local[i];
    }
    return image;
}

}  // namespace pcvr
