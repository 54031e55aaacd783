#include "pcvr/shaded.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <memory>
#include <numeric>
#include <optional>
#include <sstream>

#include "pcvr/errors.h"
#include "pcvr/kernel.h"
#include "pcvr/memory_budget.h"
#include "shaded/bricked_render.h"
#include "shaded/classify/preintegration.h"
#include "shaded/classify/shaded_levels.h"
#include "shaded/classify/transparency_culling.h"
#include "shaded/light/albedo_field.h"
#include "shaded/light/light_volume.h"
#include "shaded/reference/raycast_reference.h"
#include "shaded/sheets/sheet_sampling.h"
#include "shaded/sheets/sheet_walk.h"
#include "shaded/sheets/slab_splat.h"
#include "splat/post_convolution.h"
#include "splat/slab_footprint.h"
#include "view/block_plan.h"
#include "view/tile_set.h"

namespace pcvr {

ShadedMethod shaded_method_from_name(const std::string& name) {
    if (name == "regular") return ShadedMethod::Regular;
    if (name == "pcvr") return ShadedMethod::Pcvr;
    if (name == "bilinear_spread") return ShadedMethod::BilinearSpread;
    if (name == "raycast") return ShadedMethod::Raycast;
    throw InvalidArgument("unknown method '" + name + "' (expected regular, pcvr, bilinear_spread or raycast)");
}

SheetFill sheet_fill_from_name(const std::string& name) {
    if (name == "auto") return SheetFill::Automatic;
    if (name == "splat") return SheetFill::Splat;
    if (name == "sample") return SheetFill::Sample;
    throw InvalidArgument("unknown sheet_fill '" + name + "' (expected auto, splat or sample)");
}

Classification classification_from_name(const std::string& name) {
    if (name == "auto") return Classification::Automatic;
    if (name == "point") return Classification::Point;
    if (name == "preintegrated") return Classification::Preintegrated;
    throw InvalidArgument("unknown classification '" + name + "' (expected auto, point or preintegrated)");
}

namespace {

using Clock = std::chrono::steady_clock;

/// What "auto" means: see docs/how-it-works.md, "Pre-integrated classification".
bool preintegrates(Classification c) { return c == Classification::Preintegrated; }

/// The tiles in the order of the blocks they list, most first.
std::vector<size_t> busiest_first(const TileSet& tiles) {
    std::vector<size_t> order(tiles.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return tiles.blocks(a).size() > tiles.blocks(b).size(); });
    return order;
}

/// The largest stride splatted: 256, the tile size and the image's smaller side. A sheet's gradient
/// reads one node (a stride of pixels) beyond its tile, so each tile post-convolves its sheets a stride
/// wider on every side: near an eye automatic strides reach 65536 and took 8 GB per tile, and a stride
/// of 256 cost a 1-pixel tile or a 1-pixel-high image 500 times its pixels per sheet (both found by
/// fuzz_shaded). Where magnification is that high, few voxels fill the image: a finer subgrid costs
/// little, and it is at least as accurate.
int most_stride(const Camera& camera, const ShadedParams& params) {
    const int tile = params.tile_size > 0 ? params.tile_size : 256;
    return std::max(1, std::min({256, tile, camera.width(), camera.height()}));
}

/// Moves the blocks of strides above `most` to it (their pixel bounds, from the larger stride's
/// margin, still hold).
void cap_strides(BlockPlan& plan, int most) {
    for (auto beyond = plan.by_stride.upper_bound(most); beyond != plan.by_stride.end(); beyond = plan.by_stride.erase(beyond)) {
        std::vector<PlannedBlock>& capped = plan.by_stride[most];
        capped.insert(capped.end(), beyond->second.begin(), beyond->second.end());
    }
}

/// Sheets hold densities times slab lengths (in the sheet parameter, at most a slab's world length) in
/// float32, where voxels' contributions add up: beyond this they could leave its range (3.4e38) and
/// turn into infinities and NaN.
constexpr double kMostSheetValue = 1e36;

/// Throws InvalidArgument where a grid's densities times its scale, or their integral over a slab,
/// exceed kMostSheetValue.
void check_density_range(const ShadedVolume& v, const ShadedParams& params) {
    const Grid& grid = *v.grid;
    const auto [lo, hi] = grid.value_range();
    const double largest = std::max({std::abs(double(lo)), std::abs(double(hi)), std::abs(double(grid.background()))}) * v.density_scale;
    const double slab = largest_singular_value(grid.index_to_world()) * params.sheet_spacing;  // world units, at most
    if (largest <= kMostSheetValue && largest * std::max(1.0, slab) <= kMostSheetValue) return;
    std::ostringstream msg;
    msg << "grid '" << grid.name() << "': densities times density_scale reach " << largest << ", over slabs up to " << slab
        << " world units thick, beyond " << kMostSheetValue << " (the sheets hold them in float32, whose range ends at "
        << "3.4e38): scale the densities down with density_scale, and the transfer function's with them";
    throw InvalidArgument(msg.str());
}

void validate(const std::vector<ShadedVolume>& volumes, const ShadedParams& params, bool need_transfer_functions) {
    // Sheets (or steps) 1e-300 voxels apart, or 1e300 (their world spacing infinite), cannot work.
    if (!(params.sheet_spacing >= 1e-6 && params.sheet_spacing <= 1e6))
        throw InvalidArgument("sheet_spacing must be a number of voxels from 1e-6 to 1e6");
    if (!(params.opacity_cutoff > 0 && params.opacity_cutoff <= 1))
        throw InvalidArgument("opacity_cutoff must lie in (0, 1]");
    if (params.stride < 0) throw InvalidArgument("stride must be 0 (automatic) or a positive number of pixels");
    if (params.threads < 0) throw InvalidArgument("threads must be 0 (all cores) or positive");
    if (params.tile_size < 0) throw InvalidArgument("tile_size must be 0 (automatic) or a positive number of pixels");
    if (params.pixel_step < 1) throw InvalidArgument("pixel_step must be at least 1");
    if (params.level < -1) throw InvalidArgument("level must be -1 (automatic) or a level of detail from 0");
    if (params.samples_per_sheet < 1 || params.samples_per_sheet > 64)
        throw InvalidArgument("samples_per_sheet must be 1 to 64");
    if (params.pixel_step > 1 && params.method != ShadedMethod::Raycast)
        throw InvalidArgument("pixel_step is only supported by method 'raycast'");
    if (params.sheet_fill == SheetFill::Sample && params.method != ShadedMethod::Pcvr)
        throw InvalidArgument("sheet_fill 'sample' is only supported by method 'pcvr'");
    for (size_t i = 0; i < volumes.size(); ++i) {
        if (!volumes[i].grid) throw InvalidArgument("volume " + std::to_string(i) + " has no grid");
        if (!(volumes[i].density_scale >= 0) || !std::isfinite(volumes[i].density_scale))
            throw InvalidArgument("density_scale must be finite and >= 0");
        check_density_range(volumes[i], params);
        if (need_transfer_functions) {
            if (!volumes[i].transfer_function)
                throw InvalidArgument("grid '" + volumes[i].grid->name() + "' has no transfer function");
            volumes[i].transfer_function->validate();
        }
    }
}

/// Depths of the near and far clip planes.
std::pair<double, double> clip_depths(const Camera& camera) {
    const Mat4& w2c = camera.world_to_camera();
    auto depth_of = [&](const Vec3& p) { return -(w2c.m[2][0] * p.x + w2c.m[2][1] * p.y + w2c.m[2][2] * p.z + w2c.m[2][3]); };
    const Ray r = camera.pixel_ray(0.5 * (camera.width() - 1), 0.5 * (camera.height() - 1));
    return {depth_of(r.origin), depth_of(r.origin + r.direction)};
}

/// The sheet renderer: shaded (lighting given) or MIP (lighting null). Writes 4 or 1 floats per pixel.
/// `brick`: a brick of a bricked render (bricked_render.h), continuing `image`.
void render_sheets(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting* lighting,
                   const ShadedParams& params, RenderControl& control, ShadedStats& stats, float* image, float* depth,
                   const BrickRender* brick = nullptr) {
    const auto start = Clock::now();
    const bool mip = lighting == nullptr;
    const Kernel kernel = Kernel::from_name(params.splat_kernel);
    const PostFilterShape post_shape = post_filter_from_name(params.post_filter);
    const FootprintTable& table = FootprintTable::of(kernel);
    const DepthProfile profile(kernel);
    const bool regular = params.method == ShadedMethod::Regular;
    const bool spread = params.method == ShadedMethod::BilinearSpread;
    // Sheets sampled rather than splatted (sheet_sampling.h): `pcvr`'s shaded renders, for grids whose
    // blocks are all splatted at stride 1 (asked for: planned so), with a kernel trilinear sampling can stand in for.
    const float blur = lattice_blur(kernel);
    const bool may_sample = !mip && params.method == ShadedMethod::Pcvr && params.sheet_fill != SheetFill::Splat && blur >= 0.0f;
    const bool sample_everywhere = may_sample && params.sheet_fill == SheetFill::Sample;

    // The sheets: from the near clip plane, spaced by the finest grid's voxel along the view axis;
    // planes for orthographic views, spheres around the eye for perspective ones (in the metric where
    // the grids' voxels are cubes, when they agree on one).
    SheetGeometry geometry(camera);
    SheetLattice sheets;
    sheets.spherical = !camera.orthographic();
    sheets.eye = geometry.origin0;
    std::vector<Mat4> shapes;
    for (const ShadedVolume& v : volumes)
        if (v.grid->active_voxel_count() > 0) shapes.push_back(v.grid->index_to_world());
    sheets.metric = sheet_metric(shapes);
    stats.sheets_in_voxel_metric = !is_identity(sheets.metric);
    sheets.planes = sheet_planes(camera, sheets.metric);
    geometry.use_metric(sheets.metric, camera);
    std::vector<ViewProjection> projections;
    double spacing = INFINITY;
    for (const ShadedVolume& v : volumes) {
        projections.emplace_back(camera, v.grid->index_to_world());
        if (v.grid->active_voxel_count() > 0) spacing = std::min(spacing, depth_per_voxel(projections.back(), *v.grid, sheets));
    }
    if (!std::isfinite(spacing)) return;  // nothing to render
    const auto [near_depth, far_depth] = clip_depths(camera);
    sheets.spacing = spacing * params.sheet_spacing;
    // From one sheet in front of the near plane (samples between sheets cover the ray from there on,
    // each counting for its share between the clip planes) to the far plane; along the rays through
    // the image's corners for spheres.
    double nearest, farthest;
    if (sheets.spherical) {
        nearest = near_depth * geometry.least_metric_ray;
        farthest = far_depth * geometry.longest_metric_ray;
    } else {  // planes: u is affine over the view's box, whose corners bound it
        nearest = geometry.plane_u0_least + near_depth / geometry.plane_k;
        farthest = geometry.plane_u0_most + far_depth / geometry.plane_k;
    }
    sheets.first_depth = nearest - sheets.spacing;
    sheets.count = -sheet_floor(-(farthest - sheets.first_depth) / sheets.spacing);  // the ceiling

    SlabSplatParams splat;
    splat.kernel = &kernel;
    splat.table = &table;
    splat.profile = &profile;
    splat.mode = spread ? SlabMode::BilinearSpread : SlabMode::Footprint;

    // Each grid's blocks in view, with the stride of each: per block from its least magnified corner
    // (perspective views make depth bands), or the one asked for.
    std::vector<BlockPlan> plans;
    std::vector<const PrefilteredLattice*> lattices;  // per grid: sampled, or null
    const int largest_stride = most_stride(camera, params);
    int smallest_stride = INT32_MAX;
    for (size_t g = 0; g < volumes.size(); ++g) {
        BlockPlanParams plan_params;
        plan_params.kernel_radius = kernel.radius();
        plan_params.fixed_stride = regular || sample_everywhere ? 1 : std::min(params.stride, largest_stride);
        plan_params.nearest_stride = spread;
        plan_params.clip_planes = false;
        // Nodes outside the image reach into it through the post-filter and the gradient's stencil.
        plan_params.margin_nodes = regular ? 1 : 3;
        const ClipRegion index_clip = volumes[g].clip ? volumes[g].clip->in_index_space(volumes[g].grid->index_to_world()) : ClipRegion();
        if (!index_clip.keeps_everything()) plan_params.clip = &index_clip;
        plans.push_back(plan_blocks(volumes[g].grid->blocks(), projections[g], plan_params));
        // Where some of the grid is splatted at stride 1 (at most two pixels a voxel: footprints of a
        // few pixels), sampling it all at stride 1 measured faster than splatting it at its strides (the
        // CT head at 1024^2, strides 1-3: 1.1-1.3 times; at 1448^2, strides 2-4, splatting was faster).
        const bool finest_one = !plans.back().by_stride.empty() && plans.back().by_stride.begin()->first == 1;
        // The lattice costs 4.5 bytes a voxel of the grid's box, kept with the grid: sampled where that
        // is at most a quarter of the memory available (a 512 x 512 x 250 CT head: 304 MB).
        const std::array<int32_t, 6> box = volumes[g].grid->index_bbox();
        const bool fits = may_sample && finest_one &&
                          PrefilteredLattice::bytes(box) <= default_memory_limit() / 4;
        lattices.push_back(fits ? volumes[g].grid->prefiltered_lattice(blur) : nullptr);
        if (lattices.back() && plans.back().by_stride.size() > 1) {
            plan_params.fixed_stride = 1;
            plans.back() = plan_blocks(volumes[g].grid->blocks(), projections[g], plan_params);
        }
        cap_strides(plans.back(), largest_stride);
        for (const auto& [stride, blocks] : plans.back().by_stride) smallest_stride = std::min(smallest_stride, int(stride));
    }
    if (smallest_stride == INT32_MAX) smallest_stride = 1;

    // Each shadowed light's transmittance through every grid, before any sample needs it.
    std::optional<LightVolumes> shadows;
    if (!mip) {
        const auto shadows_start = Clock::now();
        stats.scattering_octaves = scattering_octaves(volumes, *lighting, params.shadows);
        shadows.emplace(volumes, *lighting, params.shadows, any_ambient_occlusion(volumes, *lighting), kernel, geometry.origin0,
                        control, stats.scattering_octaves);
        stats.shadow_texels = shadows->texels();
        stats.seconds_shadows = std::chrono::duration<double>(Clock::now() - shadows_start).count();
    }

    TileSet tiles(camera.width(), camera.height(), params.tile_size > 0 ? params.tile_size : automatic_tile_size(smallest_stride, camera.width(), camera.height()));
    SheetWalkSetup setup;
    std::vector<std::unique_ptr<SlabView>> views;
    std::vector<std::unique_ptr<ClassificationTable>> classifications;
    std::vector<std::shared_ptr<const PreintegrationTable>> preintegrations;
    const bool preintegrated = !mip && preintegrates(params.classification);
    stats.classification = mip ? "none" : preintegrated ? "preintegrated" : "point";
    std::vector<std::unique_ptr<Shader>> shaders;
    std::vector<std::unique_ptr<AlbedoField>> albedos;
    std::vector<std::unique_ptr<SampleClip>> sample_clips;
    std::vector<std::unique_ptr<SheetSampler>> samplers;
    std::deque<std::vector<VoxelMask>> splat_masks;  // per layer, its blocks' voxels to splat where culling left some out
    for (size_t g = 0; g < volumes.size(); ++g) {
        const ShadedVolume& volume = volumes[g];
        const Grid& grid = *volume.grid;
        const std::vector<VoxelBlock>& blocks = grid.blocks();
        const BlockPlan& plan = plans[g];
        const ClassificationTable* classification = nullptr;
        const Shader* shader = nullptr;
        if (!mip) {
            const TransferFunction& tf = *volume.transfer_function;  // its unit resolved by LevelledVolumes
            classifications.push_back(std::make_unique<ClassificationTable>(tf, tf.unit_distance));
            classification = classifications.back().get();
            albedos.push_back(AlbedoField::of(volume, geometry.origin0));
            shaders.push_back(std::make_unique<Shader>(volume.lit_by(*lighting), geometry.origin0, shadows->per_light(),
                                                       albedos.back().get(), shadows->occluders(), shadows->octaves()));
            shader = shaders.back().get();
            if (preintegrated) {
                bool built = false;
                preintegrations.push_back(PreintegrationTable::of(tf, &built));
                stats.preintegration_tables_built += built ? 1 : 0;
                if (std::count(preintegrations.begin(), preintegrations.end(), preintegrations.back()) == 1)
                    stats.preintegration_table_bytes += preintegrations.back()->bytes();
            }
        }
        const int finest = plan.by_stride.empty() ? 1 : int(plan.by_stride.begin()->first);
        const SampleClip* clip = nullptr;
        if (volume.clip && !volume.clip->keeps_everything()) {
            sample_clips.push_back(std::make_unique<SampleClip>(*volume.clip, geometry.origin0, smallest_voxel_spacing(grid)));
            clip = sample_clips.back().get();
        }
        setup.grids.push_back({classification, shader, finest, float(double(grid.background()) * volume.density_scale), clip,
                               preintegrated ? preintegrations.back().get() : nullptr});
        stats.blocks_total += plan.blocks_total;
        stats.blocks_outside += plan.blocks_culled;
        stats.blocks_clipped += plan.blocks_clipped;
        const bool cull_transparent = !mip && params.cull_transparent;
        const PrefilteredLattice* lattice = lattices[g];
        stats.grids_sampled += lattice ? 1 : 0;

        // One layer per stride; its blocks in depth and under the transfer function, each listed in the
        // tiles it reaches.
        for (const auto& [whole_stride, list] : plan.by_stride) {
            const int stride = int(whole_stride);  // the sheet renderer plans whole strides only
            splat.stride = stride;
            splat.density_scale = float(volume.density_scale);
            splat.background = grid.background();
            views.push_back(std::make_unique<SlabView>(grid, camera, sheets, splat));
            const SlabView& view = *views.back();
            const PostFilter filter(post_shape, stride);
            // Footprints splatted at stride 1 are already the pixels (the post filter would be the
            // identity): such layers skip the post-convolution and its margins, as `regular` does. Only
            // bilinear spreading needs the filter to rebuild its one-node tents there.
            const bool post_convolved = !regular && (stride > 1 || spread);
            const uint32_t layer = uint32_t(setup.layers.size());
            const SheetSampler* sampler = nullptr;
            if (lattice) {
                // A block's kernels end at most its diagonal and two reaches past their front.
                const double per_index = view.depth_reach() / kernel.radius();
                const double span = 2.0 * view.depth_reach() + std::sqrt(3.0) * (VoxelBlock::kDim - 1) * per_index;
                samplers.push_back(std::make_unique<SheetSampler>(*lattice, grid.index_to_world(), geometry,
                                                                  float(volume.density_scale), span, cull_transparent ? classification : nullptr,
                                                                  setup.grids[g].background, finest, post_shape));
                sampler = samplers.back().get();
                if (sampler->classification) ++(sampler->visibility_built ? stats.brick_visibility_built : stats.brick_visibility_reused);
            }
            setup.layers.push_back({&view, uint32_t(g), filter, post_convolved, sampler});
            if (std::find(stats.strides.begin(), stats.strides.end(), stride) == stats.strides.end()) stats.strides.push_back(stride);

            const CullingReach culling =
                culling_reach(kernel, filter, post_convolved, sheets.spacing / depth_per_voxel(projections[g], grid, sheets),
                              mip ? 1 : preintegrated ? 2 * params.samples_per_sheet : params.samples_per_sheet);
            const Vec3& n = view.projection().depth_gradient();
            const double reach = kernel.radius() * length(n);  // in depth, for the clip planes
            const double span = VoxelBlock::kDim - 1;
            const double depth_extent = span * (std::abs(n.x) + std::abs(n.y) + std::abs(n.z));
            // Pixels beyond a footprint's ellipse that its splat reaches: a node of a whole window's
            // rounding, the post filter's reach and the gradient's stencil.
            const double pixel_reach = post_convolved ? double((filter.reach_nodes() + 1) * stride + finest) : 2.0;
            // Culled in parallel (a block's voxels are tested one by one), listed in order.
            std::vector<BlockCulling> culled(cull_transparent ? list.size() : 0);
            if (cull_transparent) {
                // Sampled layers splat no voxel: their blocks only say where to sample.
                const bool single_voxels = !sampler && (!brick || brick->voxel_culling);
                const TransparencyCulling transparency(grid, volume.density_scale, culling, *classification, single_voxels);
                std::vector<VoxelMask>& masks = splat_masks.emplace_back(list.size());
                tbb::parallel_for(size_t(0), list.size(), [&](size_t i) { culled[i] = transparency.cull(list[i].index, masks[i]); });
            }
            std::vector<uint32_t> listed;
            for (size_t i = 0; i < list.size(); ++i) {
                const PlannedBlock& pb = list[i];
                const VoxelBlock& block = blocks[pb.index];
                // Depth is affine: its extremes over the block are the nearest voxel's and that plus the
                // gradient's extent over the block.
                const double nearest = view.nearest_depth(block);
                if (nearest + depth_extent + reach < near_depth || nearest - reach > far_depth) {
                    ++stats.blocks_outside;
                    continue;
                }
                const VoxelMask* splat_voxels = nullptr;
                if (cull_transparent) {
                    if (culled[i].transparent) {
                        ++stats.blocks_transparent;
                        continue;
                    }
                    stats.bricks_transparent += uint64_t(culled[i].bricks_culled);
                    stats.voxels_transparent += uint64_t(culled[i].voxels_culled);
                    splat_voxels = culled[i].splat;
                }
                tiles.add(layer, pb.index, view.front(block), pb.min_x, pb.min_y, pb.max_x, pb.max_y, pixel_reach,
                          float(view.limit_scale(block)), splat_voxels);
                listed.push_back(pb.index);
                ++stats.blocks_listed;
            }
            if (!sampler) views.back()->linearise(listed);  // sampled layers splat nothing
            stats.blocks_linearised += views.back()->blocks_linearised();
        }
        control.throw_if_cancelled();
    }
    tiles.sort();
    stats.tiles = tiles.size();
    stats.tile_size = tiles.tile_size();
    setup.tiles = &tiles;
    setup.sheets = sheets;
    setup.geometry = &geometry;
    setup.mip = mip;
    setup.opacity_cutoff = float(params.opacity_cutoff);
    setup.samples_per_sheet = params.samples_per_sheet;
    setup.preintegrated = preintegrated;
    setup.width = camera.width();
    setup.height = camera.height();
    setup.near_depth = float(near_depth);
    setup.far_depth = float(far_depth);
    setup.mip_background = float(mip_background(volumes));
    std::optional<SampleOwnership> ownership;
    if (brick) setup.owned = &ownership.emplace(brick->owned, volumes.front().grid->index_to_world(), geometry.origin0);
    stats.seconds_plan = std::chrono::duration<double>(Clock::now() - start).count();

    control.begin_phase(tiles.size(), 0.02, 1.0);
    tbb::enumerable_thread_specific<SheetWalker> walkers;
    tbb::enumerable_thread_specific<WalkStats> walk_stats;
    // Tiles cost what they list, and a head's middle tiles many times its rim's: the busiest go first
    // and each thread takes the next when it is done, so that no thread is left with a big one at the
    // end (tiles render into their own pixels: the order changes no result).
    const std::vector<size_t> order = busiest_first(tiles);
    std::atomic<size_t> next{0};
    tbb::parallel_for(0, tbb::this_task_arena::max_concurrency(), [&](int) {
        for (size_t k = next++; k < order.size(); k = next++) {
            control.throw_if_cancelled();
            walkers.local().render(setup, order[k], image, depth, walk_stats.local(), control);
            control.advance();
        }
    });
    control.throw_if_cancelled();
    WalkStats total;
    for (const WalkStats& w : walk_stats) total.add(w);
    stats.voxels_splatted = total.voxels_splatted;
    stats.voxels_occluded = total.voxels_occluded;
    stats.taps = total.taps;
    stats.samples_classified = total.samples_classified;
    stats.samples_shaded = total.samples_shaded;
    stats.tiles_terminated = total.tiles_terminated;
    stats.tile_sheets_composited = total.tile_sheets_composited;
    stats.tile_sheets_skipped = total.tile_sheets_skipped;
    stats.sheets = total.last_sheet >= total.first_sheet ? uint64_t(total.last_sheet - total.first_sheet + 1) : 0;
    stats.sheet_samples = total.sheet_samples;
    stats.sheet_samples_skipped = total.sheet_samples_skipped;
    for (int L = 1; L <= SheetSampler::kMostStride; ++L)
        if (total.sampled_strides >> L & 1u) stats.sampled_strides.push_back(L);
    stats.seconds_sampling = total.seconds_sampling;
    stats.seconds_splat = total.seconds_splat;
    stats.seconds_post_convolution = total.seconds_post_convolution;
    stats.seconds_shading = total.seconds_shading;
}

template <class Image, class Render>
Image run(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params, int channels,
          ShadedStats* stats_out, Render&& render) {
    const auto start = Clock::now();
    Image out;
    const int step = params.method == ShadedMethod::Raycast ? params.pixel_step : 1;
    out.width = (camera.width() + step - 1) / step;
    out.height = (camera.height() + step - 1) / step;
    out.pixels = ZeroedBuffer<float>(size_t(out.width) * out.height * channels);
    ShadedStats stats;
    tbb::task_arena arena(params.threads > 0 ? params.threads : tbb::task_arena::automatic);
    arena.execute([&] { render(stats, out); });
    stats.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    if (stats_out) *stats_out = std::move(stats);
    return out;
}

/// Throws InvalidArgument for what neither renderer takes: shaded (lighting given) or MIP.
void validate_call(const std::vector<ShadedVolume>& volumes, const Lighting* lighting, const ShadedParams& params) {
    validate(volumes, params, lighting != nullptr);
    if (lighting) {
        lighting->validate();
        for (const ShadedVolume& v : volumes) {
            if (!v.material) continue;
            try {
                v.lit_by(*lighting).validate();
            } catch (const InvalidArgument& e) {
                throw InvalidArgument("grid '" + v.grid->name() + "': " + e.what());
            }
        }
    }
    Kernel::from_name(params.splat_kernel);
    post_filter_from_name(params.post_filter);
}

}  // namespace

void render_brick(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting* lighting, const ShadedParams& params,
                  const BrickRender& brick, RenderControl& control, ShadedStats& stats, float* image, float* depth) {
    validate_call(volumes, lighting, params);
    const LevelledVolumes levelled(volumes, camera, 0, lighting ? LevelReduction::MeanOverBackground : LevelReduction::MaxOverBackground);
    render_sheets(levelled.volumes(), camera, lighting, params, control, stats, image, depth, &brick);
}

RgbaImage render_shaded(const std::vector<ShadedVolume>& volumes, const Camera& camera, const Lighting& lighting,
                        const ShadedParams& params, RenderControl& control, ShadedStats* stats) {
    validate_call(volumes, &lighting, params);
    const LevelledVolumes levelled(volumes, camera, params.level, LevelReduction::MeanOverBackground);
    return run<RgbaImage>(levelled.volumes(), camera, params, 4, stats, [&](ShadedStats& s, RgbaImage& image) {
        s.level = levelled.level();
        float* depth = nullptr;
        if (params.depth) {
            image.depth = ZeroedBuffer<float>(size_t(image.width) * image.height);
            std::fill(image.depth.begin(), image.depth.end(), INFINITY);
            depth = image.depth.data();
        }
        s.classification = "point";  // the sheets' choice replaces it
        if (params.method == ShadedMethod::Raycast)
            raycast_shaded(levelled.volumes(), camera, lighting, params, control, image.pixels.data(), depth);
        else
            render_sheets(levelled.volumes(), camera, &lighting, params, control, s, image.pixels.data(), depth);
    });
}

double mip_background(const std::vector<ShadedVolume>& volumes) {
    double most = volumes.empty() ? 0.0 : -INFINITY;
    for (const ShadedVolume& v : volumes) most = std::max(most, double(v.grid->background()) * v.density_scale);
    return most;
}

MipImage render_mip(const std::vector<ShadedVolume>& volumes, const Camera& camera, const ShadedParams& params,
                    RenderControl& control, ShadedStats* stats) {
    validate_call(volumes, nullptr, params);
    const LevelledVolumes levelled(volumes, camera, params.level, LevelReduction::MaxOverBackground);
    return run<MipImage>(levelled.volumes(), camera, params, 1, stats, [&](ShadedStats& s, MipImage& image) {
        s.level = levelled.level();
        // Tiles no voxel reaches are not walked.
        std::fill(image.pixels.begin(), image.pixels.end(), float(mip_background(volumes)));
        if (params.method == ShadedMethod::Raycast)
            raycast_mip(levelled.volumes(), camera, params, control, image.pixels.data());
        else
            render_sheets(levelled.volumes(), camera, nullptr, params, control, s, image.pixels.data(), nullptr);
    });
}

}  // namespace pcvr
