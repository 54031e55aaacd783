#include "splat/cut_splat.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "volume/block_voxels.h"

namespace pcvr {

VoxelBlock split_cut_block(const VoxelBlock& block, const ClipRegion& clip, double radius, double density_scale,
                           std::vector<CutVoxel>& cut) {
    VoxelBlock kept = block;
    for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
        if (!block.active(offset)) continue;
        const Vec3 c = voxel_position(block, offset);
        const ClipSide side = clip.sphere_side(c, radius);
        if (side == ClipSide::Inside) continue;
        kept.mask[offset >> 6] &= ~(uint64_t(1) << (offset & 63));
        const double value = double(block.value(offset)) * density_scale;
        if (side == ClipSide::Straddles && value != 0.0 && std::isfinite(value)) cut.push_back({c, value});
    }
    return kept;
}

namespace {

/// The pixels whose rays can meet a kernel: the projection of its bounding cube, or the whole image
/// when part of the cube lies behind the eye.
struct PixelSpan {
    int x0, y0, x1, y1;
};

PixelSpan kernel_pixels(const Vec3& c, double radius, const ViewProjection& view) {
    const Camera& cam = view.camera();
    PixelSpan all{0, 0, cam.width() - 1, cam.height() - 1};
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (int k = 0; k < 8; ++k) {
        const Vec4 p = view.to_clip({c.x + ((k & 1) ? radius : -radius), c.y + ((k & 2) ? radius : -radius),
                                     c.z + ((k & 4) ? radius : -radius)});
        if (!(p.w > 0)) return all;
        const double px = cam.pixel_x(p.x / p.w), py = cam.pixel_y(p.y / p.w);
        x0 = std::min(x0, px), x1 = std::max(x1, px), y0 = std::min(y0, py), y1 = std::max(y1, py);
    }
    return {clamp_to_int(std::ceil(x0), 0, cam.width()), clamp_to_int(std::ceil(y0), 0, cam.height()),
            clamp_to_int(std::floor(x1), -1, cam.width() - 1), clamp_to_int(std::floor(y1), -1, cam.height() - 1)};
}

}  // namespace

uint64_t splat_cut_voxels(const std::vector<CutVoxel>& voxels, const ViewProjection& view, const ClipRegion& clip,
                          const Kernel& kernel, ImageAccumulator& image, RenderControl& control) {
    if (voxels.empty()) return 0;
    const double radius = kernel.radius(), radius2 = radius * radius;
    const int width = image.width;
    tbb::enumerable_thread_specific<std::vector<float>> locals([&] { return std::vector<float>(image.pixels.size(), 0.0f); });
    tbb::enumerable_thread_specific<uint64_t> taps(0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.size(), 64), [&](const tbb::blocked_range<size_t>& range) {
        control.throw_if_cancelled();
        std::vector<float>& out = locals.local();
        uint64_t& count = taps.local();
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const CutVoxel& v = voxels[i];
            if (!ViewProjection::inside_clip_range(view.to_clip(v.centre))) continue;
            const PixelSpan span = kernel_pixels(v.centre, radius, view);
            for (int y = span.y0; y <= span.y1; ++y)
                for (int x = span.x0; x <= span.x1; ++x) {
                    // The pixel's ray with a unit direction, s measured from its closest approach.
                    const Ray ray = view.index_ray(x, y);
                    const double index_length = length(ray.direction);
                    const Vec3 unit = ray.direction / index_length;
                    const Vec3 w = v.centre - ray.origin;
                    const double closest = dot(w, unit), rho2 = dot(w, w) - closest * closest;
                    if (!(rho2 < radius2)) continue;
                    ++count;
                    const RayInterval kept = clip.ray_interval(ray.origin, unit, -1e300, 1e300);
                    if (kept.empty()) continue;
                    const double world_per_index = length(view.world_direction(x, y)) / index_length;
                    out[size_t(y) * width + x] += float(v.amplitude * world_per_index *
                                                        kernel.segment_integral(std::sqrt(std::max(rho2, 0.0)),
                                                                                kept.lo - closest, kept.hi - closest));
                }
        }
    });
    control.throw_if_cancelled();
    for (const std::vector<float>& local : locals)
        for (size_t i = 0; i < local.size(); ++i) image.pixels[i] += local[i];
    uint64_t total = 0;
    for (uint64_t t : taps) total += t;
    return total;
}

}  // namespace pcvr
