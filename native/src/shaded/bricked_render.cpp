/// @file bricked_render.cpp
/// @brief render_shaded and render_mip of a GridStream: brick by brick, front to back.
///
/// The stream is cut into bricks whose values (with the margin of voxels that the kernels, the post filter
/// and the gradients reach across a brick's faces) fit the memory limit (view/brick_order.h); each brick is
/// read from the file, rendered by the sheet renderer into the one image, owning only the samples in its
/// own box and continuing the colour and opacity (MIP: the maximum) the bricks before it left, then freed.
/// A sample is composited by exactly one brick, in the same order along its ray as in the whole grid's
/// walk, from sheets that hold the same voxels' splats: the image is the whole grid's to within float
/// rounding (the bricks sum their sheets over fewer voxels), early termination and the Depth pass included.
#include "shaded/bricked_render.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "pcvr/errors.h"
#include "pcvr/kernel.h"
#include "pcvr/memory_budget.h"
#include "pcvr/stride.h"
#include "shaded/classify/shaded_levels.h"
#include "shaded/classify/transparency_culling.h"
#include "view/block_plan.h"
#include "view/level_of_detail.h"
#include "view/tile_set.h"

namespace pcvr {

namespace {

using Clock = std::chrono::steady_clock;

std::string named(const GridStream& stream) { return "grid '" + stream.name() + "' of '" + stream.path() + "'"; }

/// Throws InvalidArgument for what needs every voxel at once: shadows and ambient occlusion (a transmittance
/// volume through the whole grid), albedo grids (held whole), the ray caster.
void refuse_whole_grid_features(const GridStream& stream, const ShadedVolume& volume, const Lighting* lighting,
                                const ShadedParams& params, const std::string& function) {
    const std::string streamed = function + ": " + named(stream) + " is streamed from its file in bricks, and ";
    const std::string instead = ": read it whole (read_vdb), or render a level of detail (level=k)";
    if (params.method == ShadedMethod::Raycast) throw InvalidArgument(streamed + "method 'raycast' marches the whole grid" + instead);
    for (const Grid* colour : volume.albedo_grids)
        if (colour) throw InvalidArgument(streamed + "albedo_grids colour the whole grid at once" + instead);
    if (!lighting) return;
    for (const Light& light : lighting->lights)
        if (light.shadow == Light::Shadow::On || (light.shadow == Light::Shadow::Default && params.shadows))
            throw InvalidArgument(streamed + "shadows need a transmittance volume through the whole grid" + instead);
    if (any_ambient_occlusion({volume}, *lighting))
        throw InvalidArgument(streamed + "ambient occlusion needs a transmittance volume through the whole grid" + instead);
}

/// Voxels beyond a brick's faces whose splats reach a sample the brick owns: the kernel's radius, the sheets
/// a sample reads beyond its own along the ray (shaded: s - 1 to s + 2 between sheets s and s + 1; MIP: s - 1
/// to s + 1), and in the sheet the post filter's two nodes and the shaded gradient's one, a node being a voxel or
/// the stride's pixels where voxels project smaller (tests/native/test_bricked_render.py's splatted images stay
/// exact with these; MIP's margin three voxels less, 2, was not).
int brick_margin(const GridStream& stream, const Camera& camera, const ShadedParams& params, bool mip) {
    const double radius = Kernel::from_name(params.splat_kernel).radius();
    const auto magnification = corner_pixels_per_voxel(stream.index_bbox(), stream.index_to_world(), camera);
    const double least = magnification ? std::max(magnification->first, 1e-3) : 1.0;
    const double node = std::max(1.0, std::max(params.stride, 1) / least);
    const double sheets = (mip ? 1.0 : 2.0) * std::max(1.0, params.sheet_spacing);
    return int(std::ceil(radius + sheets + (mip ? 2.0 : 3.0) * node));
}

/// `params` with the sheets sampled or splatted as the grid read whole would choose them ("auto": shaded.cpp
/// samples every sheet of a grid where some block splats at stride 1 and its lattice takes at most a quarter of
/// the memory available), where a brick alone might choose otherwise: its own lattice always fits, and its
/// finest stride may not be 1.
ShadedParams bricks_fill_sheets_as_whole(const GridStream& stream, const Camera& camera, const ShadedParams& params) {
    ShadedParams chosen = params;
    if (params.sheet_fill != SheetFill::Automatic) return chosen;
    const auto least = corner_pixels_per_voxel(stream.index_bbox(), stream.index_to_world(), camera, VoxelAxis::LeastMagnified);
    const bool finest_one = params.stride > 0 ? params.stride == 1 : least && automatic_stride(least->first) == 1;
    const bool fits = PrefilteredLattice::elements(stream.index_bbox()) * sizeof(float) <= default_memory_limit() / 4;
    chosen.sheet_fill = finest_one && fits ? SheetFill::Sample : SheetFill::Splat;
    return chosen;
}

/// `part`'s counts and thread seconds added into `total`, its extremes and lists merged.
void accumulate(ShadedStats& total, const ShadedStats& part) {
    for (uint64_t ShadedStats::*count :
         {&ShadedStats::blocks_total, &ShadedStats::blocks_outside, &ShadedStats::blocks_clipped, &ShadedStats::blocks_transparent,
          &ShadedStats::bricks_transparent, &ShadedStats::voxels_transparent, &ShadedStats::blocks_listed,
          &ShadedStats::blocks_linearised, &ShadedStats::voxels_splatted, &ShadedStats::voxels_occluded, &ShadedStats::taps,
          &ShadedStats::samples_classified, &ShadedStats::samples_shaded, &ShadedStats::tiles, &ShadedStats::tiles_terminated,
          &ShadedStats::tile_sheets_composited, &ShadedStats::tile_sheets_skipped, &ShadedStats::sheet_samples,
          &ShadedStats::sheet_samples_skipped, &ShadedStats::preintegration_tables_built})
        total.*count += part.*count;
    for (uint64_t ShadedStats::*most : {&ShadedStats::sheets, &ShadedStats::grids_sampled, &ShadedStats::preintegration_table_bytes})
        total.*most = std::max(total.*most, part.*most);
    for (double ShadedStats::*seconds : {&ShadedStats::seconds_plan, &ShadedStats::seconds_splat, &ShadedStats::seconds_post_convolution,
                                         &ShadedStats::seconds_sampling, &ShadedStats::seconds_shading})
        total.*seconds += part.*seconds;
    for (auto [into, from] : {std::pair{&total.sampled_strides, &part.sampled_strides}, std::pair{&total.strides, &part.strides}}) {
        for (int stride : *from)
            if (std::find(into->begin(), into->end(), stride) == into->end()) into->push_back(stride);
        std::sort(into->begin(), into->end());
    }
    total.sheets_in_voxel_metric = total.sheets_in_voxel_metric || part.sheets_in_voxel_metric;
    total.tile_size = std::max(total.tile_size, part.tile_size);
    if (part.classification != "none" || total.classification.empty()) total.classification = part.classification;
}

/// The level a stream renders from: ShadedParams::level, or for "auto" as LevelledVolumes chooses for the
/// grid read whole; at most GridStream::kMaxLevel.
int stream_level(const GridStream& stream, const Camera& camera, const ShadedParams& params) {
    if (stream.active_voxel_count() == 0) return 0;
    const int level = params.level >= 0 ? params.level
                                        : automatic_level(stream.index_bbox(), stream.index_to_world(), camera, kShadedLevelPixelsPerVoxel);
    return std::min(level, GridStream::kMaxLevel);
}

/// The stream's volume as its bricks render it: the transfer function's unit resolved from level 0's voxels.
struct StreamVolume {
    TransferFunction transfer_function;
    ShadedVolume volume;

    StreamVolume(const GridStream& stream, const ShadedVolume& like) : volume(like) {
        if (!like.transfer_function) return;
        transfer_function = *like.transfer_function;
        const Mat4& m = stream.index_to_world();
        if (!(transfer_function.unit_distance > 0))
            transfer_function.unit_distance = std::min({length(m.column(0)), length(m.column(1)), length(m.column(2))});
        volume.transfer_function = &transfer_function;
    }
};

/// Whether the grid read whole would cull its voxels one by one: it has voxel value ranges only up to
/// VoxelValueRanges::kMostBlocks blocks (a leaf, or 8^3 voxels of a tile, a block). Bricks, each far
/// smaller, follow it: the same voxels culled, and no ranges built per brick that the whole grid skips
/// (they took 4.8 of the 17 s a 512 x 512 x 361 CT's 48 bricks took).
bool whole_grid_culls_voxels(const std::vector<std::array<int32_t, 6>>& value_boxes) {
    uint64_t blocks = 0;
    for (const auto& b : value_boxes)
        blocks += (uint64_t(b[3] - b[0] + 1) * uint64_t(b[4] - b[1] + 1) * uint64_t(b[5] - b[2] + 1) + VoxelBlock::kSize - 1) /
                  VoxelBlock::kSize;
    return blocks <= VoxelValueRanges::kMostBlocks;
}

/// The memory a bricked render holds at once: the image (and the Depth pass) all along, each thread's tile
/// and sheet buffers, and one brick's values with what the renderer builds over them.
struct WorkingSet {
    uint64_t image = 0;
    uint64_t threads = 0;        ///< the threads' tile planes and sheet rings, and kUnmodelledBytes
    double per_value_byte = 1;   ///< bytes a brick holds per byte of its values
    uint64_t per_box_voxel = 0;  ///< bytes per voxel of a brick's read box (its prefiltered lattice)

    uint64_t with_brick(const BrickSides& sides, int margin, uint64_t values) const {
        uint64_t box = 1;
        for (int side : sides) box *= uint64_t(side + 2 * margin + 2 * PrefilteredLattice::kMargin);
        return image + threads + uint64_t(std::ceil(double(values) * per_value_byte)) + box * per_box_voxel;
    }
};

/// Per 8^3 block of a brick's values (2 KiB of them): its VoxelBlock, its value ranges and the halves they
/// are built from, its splat mask, plan, culling and tile entries, the tree's leaf and the blocks' index.
constexpr uint64_t kBytesPerBlock = sizeof(VoxelBlock) + sizeof(BlockValueRange) + 8 * 2 * sizeof(float) + sizeof(VoxelMask) +
                                    sizeof(BlockCulling) + sizeof(PlannedBlock) + 2 * sizeof(TileBlock) + 128;
/// Per block, while transparency culling builds the value ranges: the lattice of its bricks' ranges they are
/// built on, over a box at most twice the blocks (sparser ones use the index above: block_value_ranges.cpp).
constexpr uint64_t kRangeLatticeBytesPerBlock = 2 * 8 * 2 * sizeof(float);
/// A thread's buffers (sheet_walk.cpp): per pixel of its tile, four colour planes, the depth and the MIP's
/// maximum; per pixel of the tile grown by the gradient's halo and the splat windows' margins (16 at most at
/// the strides bricks render), each layer's ring of sheets and the grid's four slots of post-convolved ones.
uint64_t thread_bytes(const GridStream& stream, const Camera& camera, const ShadedParams& params) {
    int smallest_stride = std::max(params.stride, 1), layers = 1;
    if (params.stride == 0) {
        // The most magnified voxels take the largest stride: the tile grows with the smallest.
        const auto corners = corner_pixels_per_voxel(stream.index_bbox(), stream.index_to_world(), camera);
        const int least = corners ? automatic_stride(corners->first) : 1, most = corners ? automatic_stride(corners->second) : 1;
        smallest_stride = most;
        layers = int(std::floor(std::log2(double(most) / least))) + 1;  // strides a band of kStrideBandRatio apart, at most
    }
    const int tile = params.tile_size > 0 ? params.tile_size : automatic_tile_size(smallest_stride, camera.width(), camera.height());
    const uint64_t tile_pixels = uint64_t(std::min(tile, camera.width())) * uint64_t(std::min(tile, camera.height()));
    const uint64_t grown = uint64_t(std::min(tile, camera.width()) + 32) * uint64_t(std::min(tile, camera.height()) + 32);
    const Kernel kernel = Kernel::from_name(params.splat_kernel);
    const uint64_t ring = uint64_t(std::ceil(2.0 * kernel.radius() / std::min(1.0, params.sheet_spacing))) + 8;
    return sizeof(float) * (6 * tile_pixels + grown * (uint64_t(layers) * ring + 4));
}

/// What the model above leaves out (the reads' leaf lists, the allocator's headers, the caller's stats): the
/// measured peak above the open file exceeded the model by 1.3 to 3 MiB at 32 to 64 MiB limits on the
/// 512 x 512 x 361 CT of tests/bench/big_volume_bench.py (heaptrack: the rest is as modelled).
constexpr uint64_t kUnmodelledBytes = uint64_t(4) << 20;

WorkingSet working_set(const GridStream& stream, const Camera& camera, const ShadedParams& params, bool mip, bool voxel_culling) {
    WorkingSet set;
    const uint64_t pixels = uint64_t(camera.width()) * uint64_t(camera.height());
    set.image = pixels * sizeof(float) * (mip ? 1 : params.depth ? 5 : 4);
    const int threads = params.threads > 0 ? params.threads : tbb::this_task_arena::max_concurrency();
    set.threads = uint64_t(threads) * thread_bytes(stream, camera, params) + kUnmodelledBytes;
    const bool culls = !mip && params.cull_transparent;
    set.per_value_byte = 1.0 + double(kBytesPerBlock + (culls ? kRangeLatticeBytesPerBlock : 0) +
                                      (culls && voxel_culling ? 2 * VoxelBlock::kSize : 0)) /
                                   double(VoxelBlock::kSize * sizeof(float));
    if (!mip && params.sheet_fill == SheetFill::Sample) set.per_box_voxel = sizeof(float);
    return set;
}

/// The bricks a stream renders in, and the memory their render holds.
struct BrickCut {
    BrickSides sides{0, 0, 0};
    int margin = 0;
    std::vector<Brick> bricks;
    BrickRender render;          ///< what every brick's render shares (its `owned` set per brick)
    WorkingSet memory;
    uint64_t planning_bytes = 0; ///< held while cutting: the image and the boxes of the grid's values

    uint64_t most_bytes() const {
        uint64_t most = planning_bytes;
        for (const Brick& brick : bricks) most = std::max(most, memory.with_brick(sides, margin, brick.bytes));
        return most;
    }
};

/// Bricks as large as `bricked.memory_limit` lets a brick's render be (WorkingSet; without a limit, of the
/// stream's batch bytes of values, or the default's). The grid's value boxes (24 bytes a leaf) are freed
/// before any brick is read.
BrickCut cut_stream(const GridStream& stream, const Camera& camera, const ShadedParams& params, const BrickedParams& bricked,
                    bool mip, const std::string& function) {
    BrickCut cut;
    cut.margin = brick_margin(stream, camera, params, mip);
    const int margin = cut.margin;
    const std::vector<std::array<int32_t, 6>> boxes = stream.value_boxes();
    cut.render.voxel_culling = whole_grid_culls_voxels(boxes);
    cut.memory = working_set(stream, camera, params, mip, cut.render.voxel_culling);
    cut.planning_bytes = cut.memory.image + boxes.capacity() * sizeof(boxes[0]);
    const WorkingSet& memory = cut.memory;
    uint64_t most_values = bricked.brick_bytes > 0 ? bricked.brick_bytes : stream.batch_bytes();
    if (most_values == 0 && bricked.memory_limit == 0) most_values = GridStream::kDefaultBatchBytes;
    cut.sides = brick_sides(boxes, margin, [&](const BrickSides& at, uint64_t values) {
        if (most_values > 0 && values > most_values) return false;
        return bricked.memory_limit == 0 || memory.with_brick(at, margin, values) <= bricked.memory_limit;
    });
    if (cut.sides[0] == 0) {
        // At most this many whole leaves (8^3 voxels) meet a side of 16 and its margins.
        const uint64_t leaves = uint64_t((16 + 2 * margin + 7) / 8 + 1);
        const uint64_t least_values = leaves * leaves * leaves * VoxelBlock::kSize * sizeof(float);
        const uint64_t least = memory.with_brick({16, 16, 16}, margin, least_values);
        if (bricked.memory_limit == 0 || least <= bricked.memory_limit)
            throw InvalidArgument(function + ": " + named(stream) + ": bricks of at most " + std::to_string(most_values) +
                                  " bytes of values (brick_bytes, or the stream's batch_bytes) are too few for 16^3 voxels and the " +
                                  std::to_string(margin) + " voxels around them that its kernels reach; allow at least " +
                                  std::to_string(least_values));
        throw InvalidArgument(function + ": " + named(stream) + ": memory_limit of " + std::to_string(bricked.memory_limit) +
                              " bytes is below what one brick's render holds: the image (" + std::to_string(memory.image) +
                              " bytes), the threads' tile buffers and what reading takes (" + std::to_string(memory.threads) + ") and a brick of 16^3 voxels "
                              "with the " + std::to_string(margin) + " voxels around it that its kernels reach, and what is built over "
                              "them; raise memory_limit to at least " + std::to_string(least) + " bytes (or render fewer pixels or "
                              "threads)");
    }
    cut.bricks = cut_into_bricks(boxes, cut.sides, margin);
    return cut;
}

/// Renders the stream's share of bricks into `image` (and `depth`), which hold the empty image.
void render_bricks(const GridStream& stream, const ShadedVolume& volume, const Camera& camera, const Lighting* lighting,
                   const ShadedParams& params, const BrickedParams& bricked, RenderControl& control, ShadedStats& stats,
                   float* image, float* depth) {
    const ShadedParams brick_params = bricks_fill_sheets_as_whole(stream, camera, params);
    BrickCut cut = cut_stream(stream, camera, brick_params, bricked, lighting == nullptr, lighting ? "render_shaded" : "render_mip");
    const std::vector<Brick>& bricks = cut.bricks;
    BrickRender& render = cut.render;
    const std::vector<size_t> order = visibility_order(bricks, cut.sides, camera, stream.index_to_world());
    const size_t first = order.size() * bricked.share / bricked.shares, last = order.size() * (bricked.share + 1) / bricked.shares;
    tbb::task_arena arena(params.threads > 0 ? params.threads : tbb::task_arena::automatic);
    for (size_t k = first; k < last; ++k) {
        control.throw_if_cancelled();
        control.set_span(double(k - first) / double(last - first), double(k + 1 - first) / double(last - first));
        const Brick& brick = bricks[order[k]];
        const Grid part = stream.read_box(brick.read_box);
        ShadedVolume at_brick = volume;
        at_brick.grid = &part;
        ShadedStats part_stats;
        render.owned = brick.owned;
        arena.execute([&] { render_brick({at_brick}, camera, lighting, brick_params, render, control, part_stats, image, depth); });
        accumulate(stats, part_stats);
        ++stats.batches;
    }
    stats.memory_bytes = cut.most_bytes();
    control.set_span(0.0, 1.0);
}

void check_share(const GridStream& stream, const BrickedParams& bricked, const std::string& function) {
    if (!stream.only_batches().empty())
        throw InvalidArgument(function + ": " + named(stream) + " is restricted to some of its batches (with_batches), which "
                              "splits an X-ray; shaded and MIP split a frame with brick_share");
    if (bricked.shares == 0 || bricked.share >= bricked.shares)
        throw InvalidArgument(function + ": " + named(stream) + ": share " + std::to_string(bricked.share) + " of " +
                              std::to_string(bricked.shares) + " bricks' shares does not exist (shares count from 0)");
}

}  // namespace

RgbaImage render_shaded(const GridStream& stream, const ShadedVolume& volume, const Camera& camera, const Lighting& lighting,
                        const ShadedParams& params, const BrickedParams& bricked, RenderControl& control, ShadedStats* stats_out) {
    const auto start = Clock::now();
    refuse_whole_grid_features(stream, volume, &lighting, params, "render_shaded");
    check_share(stream, bricked, "render_shaded");
    const StreamVolume resolved(stream, volume);
    ShadedVolume like = resolved.volume;
    const int level = stream_level(stream, camera, params);
    if (level > 0) {  // a coarse level in memory; the first share renders all of it
        const Grid coarse = stream.level(level, LevelReduction::MeanOverBackground, &control);
        like.grid = &coarse;
        ShadedParams at_level = params;
        at_level.level = 0;
        RgbaImage image = render_shaded({like}, camera, lighting, at_level, control, stats_out);
        if (bricked.share > 0) std::fill(image.pixels.begin(), image.pixels.end(), 0.0f);
        if (bricked.share > 0 && params.depth) std::fill(image.depth.begin(), image.depth.end(), INFINITY);
        if (stats_out) stats_out->level = level;
        return image;
    }
    RgbaImage image;
    image.width = camera.width(), image.height = camera.height();
    image.pixels = ZeroedBuffer<float>(size_t(image.width) * image.height * 4);
    if (params.depth) {
        image.depth = ZeroedBuffer<float>(size_t(image.width) * image.height);
        std::fill(image.depth.begin(), image.depth.end(), INFINITY);
    }
    ShadedStats stats;
    render_bricks(stream, like, camera, &lighting, params, bricked, control, stats, image.pixels.data(),
                  params.depth ? image.depth.data() : nullptr);
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (stats_out) *stats_out = std::move(stats);
    return image;
}

MipImage render_mip(const GridStream& stream, const ShadedVolume& volume, const Camera& camera, const ShadedParams& params,
                    const BrickedParams& bricked, RenderControl& control, ShadedStats* stats_out) {
    const auto start = Clock::now();
    refuse_whole_grid_features(stream, volume, nullptr, params, "render_mip");
    check_share(stream, bricked, "render_mip");
    ShadedVolume like = volume;
    const float background = float(double(stream.background()) * volume.density_scale);
    const int level = stream_level(stream, camera, params);
    if (level > 0) {
        const Grid coarse = stream.level(level, LevelReduction::MaxOverBackground, &control);
        like.grid = &coarse;
        ShadedParams at_level = params;
        at_level.level = 0;
        MipImage image = render_mip({like}, camera, at_level, control, stats_out);
        if (bricked.share > 0) std::fill(image.pixels.begin(), image.pixels.end(), background);
        if (stats_out) stats_out->level = level;
        return image;
    }
    MipImage image;
    image.width = camera.width(), image.height = camera.height();
    image.pixels = ZeroedBuffer<float>(size_t(image.width) * image.height);
    std::fill(image.pixels.begin(), image.pixels.end(), background);  // rays that meet no voxel
    ShadedStats stats;
    render_bricks(stream, like, camera, nullptr, params, bricked, control, stats, image.pixels.data(), nullptr);
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (stats_out) *stats_out = std::move(stats);
    return image;
}

}  // namespace pcvr
