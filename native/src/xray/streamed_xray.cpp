/// @file streamed_xray.cpp
/// @brief render_xray over grids streamed from their files (grid_stream.h): one render per batch, summed.
#include <algorithm>
#include <chrono>
#include <string>

#include "pcvr/errors.h"
#include "pcvr/xray.h"

#include "view/level_of_detail.h"
#include "xray/supersampling.h"

namespace pcvr {

namespace {

/// `part`'s counts added into `total`; ranges widened.
void accumulate(XrayStats& total, const XrayStats& part) {
    total.voxels_splatted += part.voxels_splatted;
    total.blocks_total += part.blocks_total;
    total.blocks_culled += part.blocks_culled;
    total.blocks_clipped += part.blocks_clipped;
    total.voxels_cut += part.voxels_cut;
    total.taps += part.taps;
    total.pixels_negative_corrected += part.pixels_negative_corrected;
    total.batches += part.batches;
    total.nonnegative = total.nonnegative && part.nonnegative;
    total.level = std::max(total.level, part.level);
    total.supersampling = std::max(total.supersampling, part.supersampling);
    total.memory_bytes = std::max(total.memory_bytes, part.memory_bytes);
    total.include_magnification(part.min_magnification, part.max_magnification);
    for (double stride : part.strides)
        if (std::find(total.strides.begin(), total.strides.end(), stride) == total.strides.end())
            total.strides.push_back(stride);
}

/// The level of detail a stream renders from: as render_xray chooses for a grid (level_of_detail.h), over
/// the whole stream's box so that every batch takes the same, and at most GridStream::kMaxLevel.
int stream_level(const GridStream& stream, const Camera& camera, const XrayParams& params) {
    if (params.method == XrayMethod::Exact || stream.active_voxel_count() == 0) return 0;
    const int level = params.level >= 0 ? params.level
                      : params.antialias ? automatic_level(stream.index_bbox(), stream.index_to_world(), camera)
                                         : 0;
    return std::min(level, GridStream::kMaxLevel);
}

/// The sub-pixels per pixel edge a stream's batches render at: as render_xray chooses for a grid at an
/// automatic level 0, over the whole stream's box, where it pays for the batches of `batch_bytes` (each
/// batch supersamples the whole image).
int stream_supersampling(const GridStream& stream, const Camera& camera, const XrayParams& params, int level,
                         uint64_t batch_bytes) {
    if (params.supersampling > 0) return params.supersampling;
    if (!may_supersample(params) || level > 0 || stream.active_voxel_count() == 0) return 1;
    const uint64_t batches = std::max<uint64_t>(stream.batch_count(batch_bytes), 1);
    return supersampling_that_pays(automatic_supersampling(stream.index_bbox(), stream.index_to_world(), camera),
                                   camera, stream.active_voxel_count() / batches);
}

/// The least and most pixels per voxel of level `level` over the whole stream's box (least magnified
/// direction): what regular splatting's passband compensation takes in every batch, as for the grid read whole.
std::pair<double, double> stream_magnification(const GridStream& stream, const Camera& camera, int level) {
    if (stream.active_voxel_count() == 0) return {0.0, 0.0};
    const auto corners = corner_pixels_per_voxel(stream.index_bbox(), stream.index_to_world(), camera, VoxelAxis::LeastMagnified);
    if (!corners) return {0.0, 0.0};
    const double scale = std::ldexp(1.0, level);
    return {corners->first * scale, corners->second * scale};
}

}  // namespace

XrayImage render_xray(const std::vector<WeightedGrid>& grids, const std::vector<WeightedStream>& streams,
                      const Camera& camera, const XrayParams& params, RenderControl& control, XrayStats* stats_out) {
    if (streams.empty()) return render_xray(grids, camera, params, control, stats_out);
    const auto start = std::chrono::steady_clock::now();
    // The batches' values come out of the memory limit: half of it unless a stream asks for its own
    // size, then what that leaves for the buffers.
    uint64_t batch_bytes = params.memory_limit > 0 ? params.memory_limit / 2 : GridStream::kDefaultBatchBytes;
    for (const WeightedStream& s : streams)
        if (s.stream->batch_bytes() > 0) batch_bytes = std::min(batch_bytes, s.stream->batch_bytes());
    XrayParams part_params = params;
    // The sum of the batches is cleared below zero, not each: a batch's faces are sharp edges of its own.
    part_params.keep_nonnegative = false;
    if (params.memory_limit > 0) {
        if (batch_bytes >= params.memory_limit)
            throw InvalidArgument("render_xray: memory_limit (" + std::to_string(params.memory_limit) +
                                  " bytes) leaves nothing for the buffers beside the streams' batches of " +
                                  std::to_string(batch_bytes) + " bytes");
        part_params.memory_limit = params.memory_limit - batch_bytes;
    }

    uint64_t total_voxels = 0;
    for (const WeightedGrid& g : grids) total_voxels += g.grid->active_voxel_count();
    for (const WeightedStream& s : streams) total_voxels += s.stream->active_voxel_count();
    const double per_voxel = 1.0 / double(std::max<uint64_t>(total_voxels, 1));

    XrayImage image;
    bool first_part = true;
    XrayStats stats;
    uint64_t voxels_before = 0;  // voxels of the renders before this one
    auto render_part = [&](const std::vector<WeightedGrid>& part, uint64_t voxels, const XrayParams& with) {
        control.throw_if_cancelled();
        control.set_span(double(voxels_before) * per_voxel, double(voxels_before + voxels) * per_voxel);
        XrayStats part_stats;
        XrayImage rendered = render_xray(part, camera, with, control, &part_stats);
        accumulate(stats, part_stats);
        voxels_before += voxels;
        if (first_part) {
            image = std::move(rendered);
            first_part = false;
            return;
        }
        for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] += rendered.pixels[i];
    };
    if (!grids.empty()) {
        uint64_t voxels = 0;
        for (const WeightedGrid& g : grids) voxels += g.grid->active_voxel_count();
        render_part(grids, voxels, part_params);
    }
    for (const WeightedStream& s : streams) {
        const int level = stream_level(*s.stream, camera, params);
        // A zoomed-out view: the level fits where a batch would, and stays for the next render. Not with an
        // attenuation map, which must see every voxel before levels average them (batches map, then reduce),
        // nor for a stream of some batches only, which renders just them (the coarse level is the whole grid's).
        if (level > 0 && !s.attenuation && s.stream->only_batches().empty() &&
            (s.stream->value_bytes() >> (3 * level)) <= batch_bytes) {
            const Grid coarse = s.stream->level(level, LevelReduction::MeanOverZero, &control);
            render_part({WeightedGrid{&coarse, s.density_scale, level, nullptr, s.clip}}, s.stream->active_voxel_count(), part_params);
            continue;
        }
        XrayParams batch_params = part_params;
        batch_params.level = level;  // every batch the same level, and the same sub-pixels
        batch_params.supersampling = stream_supersampling(*s.stream, camera, params, level, batch_bytes);
        batch_params.compensation_magnification = stream_magnification(*s.stream, camera, level);
        uint64_t streamed = 0;
        s.stream->for_each_batch(batch_bytes, [&](const GridStream::Batch& batch) {
            render_part({WeightedGrid{&batch.grid, s.density_scale, 0, s.attenuation, s.clip}}, batch.voxels_done - streamed,
                        batch_params);
            streamed = batch.voxels_done;
        });
    }
    control.set_span(0.0, 1.0);
    // A field >= 0 renders >= 0: the batches were sharpened unlimited (their images add up to the whole render's),
    // so the sum's ringing below zero is cleared, its mass taken from the overshoot beside it.
    // Not for a share of the batches (with_batches): the shares must add up to the whole.
    bool share = false;
    for (const WeightedStream& s : streams) share |= !s.stream->only_batches().empty();
    if (params.keep_nonnegative && stats.nonnegative && !share)
        stats.pixels_negative_corrected += clear_negative_pixels(image.pixels, image.width, image.height, ringing_reach(stats));
    stats.memory_bytes += batch_bytes;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (stats_out) *stats_out = stats;
    return image;
}

std::pair<double, double> effective_magnification(const GridStream& stream, const Camera& camera) {
    if (stream.active_voxel_count() == 0) return {0.0, 0.0};
    return corner_pixels_per_voxel(stream.index_bbox(), stream.index_to_world(), camera).value_or(std::pair<double, double>{0.0, 0.0});
}

}  // namespace pcvr
