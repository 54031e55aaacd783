#include "pcvr/xray.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <string>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "pcvr/errors.h"
#include "pcvr/kernel.h"
#include "pcvr/memory_budget.h"
#include "splat/cut_splat.h"
#include "splat/passband.h"
#include "splat/post_convolution.h"
#include "splat/splatter.h"
#include "view/block_plan.h"
#include "xray/exact_xray.h"

#include "splat/near_eye_splat.h"
#include "view/level_of_detail.h"
#include "xray/supersampling.h"

namespace pcvr {

XrayMethod xray_method_from_name(const std::string& name) {
    if (name == "regular") return XrayMethod::Regular;
    if (name == "pcvr") return XrayMethod::Pcvr;
    if (name == "bilinear_spread") return XrayMethod::BilinearSpread;
    if (name == "exact") return XrayMethod::Exact;
    throw InvalidArgument("unknown method '" + name + "' (expected regular, pcvr, bilinear_spread or exact)");
}

Passband passband_from_name(const std::string& name) {
    if (name == "compensated") return Passband::Compensated;
    if (name == "paper") return Passband::Paper;
    throw InvalidArgument("unknown passband '" + name + "' (expected compensated or paper)");
}

namespace {

/// One grid ready to splat: its view and which of its blocks go to which stride.
struct PlannedGrid {
    const WeightedGrid* source;
    const Grid* level_grid;  ///< the level of detail of source->grid that is splatted
    int level;
    ViewProjection view;
    ClipRegion clip;  ///< the grid's clip region in the level's index space (keeps everything without one)
    BlockPlan plan;
};

/// Throws OutOfMemory before anything large is allocated when `budget` does not fit.
void check_memory(MemoryBudget& budget, const Camera& cam, XrayStats& stats) {
    stats.memory_bytes = budget.total();
    budget.check("render_xray of a " + std::to_string(cam.width()) + " x " + std::to_string(cam.height()) + " image");
}

std::string copies(int workers) { return ", " + std::to_string(workers + 1) + " copies (one per thread, and their sum)"; }

/// A power of two that brings the largest |density x density_scale| of the grids near 1 (within
/// 2^+-100). The splats' float stages (amplitudes, block tiles) multiply it in and the image divides
/// it out: densities from denormals to 3e38 then neither underflow to zero nor overflow on the way,
/// and a power of two rounds nothing else.
double range_scale(const std::vector<WeightedGrid>& grids) {
    double largest = 0;
    for (const WeightedGrid& g : grids) {
        const auto [lo, hi] = g.grid->value_range();
        const double magnitude = std::max(std::abs(double(lo)), std::abs(double(hi))) * std::abs(g.density_scale);
        if (std::isfinite(magnitude)) largest = std::max(largest, magnitude);
    }
    if (!(largest > 0)) return 1.0;
    return std::ldexp(1.0, std::clamp(-std::ilogb(largest), -100, 100));
}

/// The passband compensation of one render's splat grids (src/splat/passband.h).
class Compensation {
public:
    /// `bands`: per stride, the magnifications of the grids splatted at it; `regular_range`: the
    /// magnifications regular splatting compensates for (one image holds every depth).
    Compensation(const XrayParams& params, const Kernel& kernel, PostFilterShape post_shape, const Camera& cam,
                 std::map<double, XrayStats> bands, std::pair<double, double> regular_range)
        : on_(params.passband == Passband::Compensated &&
              (params.method == XrayMethod::Pcvr || params.method == XrayMethod::Regular)),
          regular_(params.method == XrayMethod::Regular),
          perspective_(!cam.orthographic()),
          kernel_variance_(kernel.variance()),
          post_shape_(post_shape),
          pixel_mean_(params.antialias),
          bands_(std::move(bands)),
          regular_range_(regular_range) {}

    /// Sharpens a depth band's splat grid before it goes to the image.
    void apply(SplatGrid& grid, RenderControl& control) const {
        if (!on_) return;
        if (regular_) {
            if (!(regular_range_.first > 0)) return;
            // The image's taps a whole number of pixels apart, about a voxel.
            const double m = std::sqrt(regular_range_.first * regular_range_.second);
            const int d = std::max(1, int(std::lround(m)));
            sharpen_nodes(grid, passband_sharpening(kernel_variance_ * (m / d) * (m / d)), d, control);
            return;
        }
        const auto band = bands_.find(grid.stride());
        if (band == bands_.end() || !(band->second.max_magnification > 0)) return;
        // Orthographic, an automatic stride is its voxels' magnification (from 1 up); a perspective band's
        // strides fall in steps of kPerspectiveBandRatio from its most magnified voxels: they lie about half a
        // step below.
        const double s = grid.stride();
        const double m = std::clamp(perspective_ ? s / std::sqrt(kPerspectiveBandRatio) : s, band->second.min_magnification,
                                    band->second.max_magnification);
        sharpen_nodes(grid, passband_sharpening(kernel_variance_ * (m / s) * (m / s) + post_filter_blur(post_shape_, s, pixel_mean_)), 1, control);
    }

private:
    bool on_, regular_, perspective_;
    double kernel_variance_;
    PostFilterShape post_shape_;
    bool pixel_mean_;
    std::map<double, XrayStats> bands_;
    std::pair<double, double> regular_range_;
};

}  // namespace

namespace {

}  // namespace

uint64_t clear_negative_pixels(float* pixels, int width, int height, int radius) {
    // Pixel p's deficit d_p goes to the positive pixels q within `radius` in proportion to them, q d_p / H_p with
    // H_p their sum around p: q loses q times the sum of d / H over the negative pixels around it. All at once,
    // in any order, within the box of the negative pixels widened by `radius` (nothing else changes).
    // Undershoots within float's rounding of the peak (a Gaussian's cut tails) are set to zero: their mass is below
    // 1e-6 of a pixel's at the peak each.
    const float peak = width > 0 && height > 0 ? *std::max_element(pixels, pixels + size_t(width) * height) : 0.0f;
    const float negligible = -1e-6f * std::max(peak, 0.0f);
    uint64_t cleared = 0;
    std::vector<uint32_t> negative;  // pixel indices, 4 bytes each: an image of 2^32 pixels or more is only set to zero
    const bool indexable = uint64_t(width) * uint64_t(height) < (uint64_t(1) << 32);
    int x0 = width, x1 = -1, y0 = height, y1 = -1;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            float& p = pixels[size_t(y) * width + x];
            if (!(p < 0)) continue;
            ++cleared;
            if (p >= negligible || !indexable) {
                p = 0;
                continue;
            }
            negative.push_back(uint32_t(size_t(y) * width + x)), x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
    if (negative.empty()) return cleared;
    x0 = std::max(0, x0 - radius), x1 = std::min(width - 1, x1 + radius), y0 = std::max(0, y0 - radius), y1 = std::min(height - 1, y1 + radius);
    // Each deficit's share of the positive pixels around it (from the pixels as they are), then band by band of
    // rows the sum of the shares around each pixel: a band's worth of memory, whatever the image.
    std::vector<float> share(negative.size(), 0.0f);
    for (size_t n = 0; n < negative.size(); ++n) {
        const int x = int(negative[n] % size_t(width)), y = int(negative[n] / size_t(width));
        double held = 0;
        for (int v = std::max(0, y - radius); v <= std::min(height - 1, y + radius); ++v)
            for (int u = std::max(0, x - radius); u <= std::min(width - 1, x + radius); ++u) held += std::max(0.0f, pixels[size_t(v) * width + u]);
        if (held > 0) share[n] = float(-double(pixels[negative[n]]) / held);
    }
    constexpr int kBandRows = 64;
    const int w = x1 - x0 + 1;
    std::vector<double> taken;
    size_t first = 0;  // the first negative pixel within reach of the band (they are in row order)
    for (int band = y0; band <= y1; band += kBandRows) {
        const int rows = std::min(kBandRows, y1 - band + 1);
        taken.assign(size_t(rows) * w, 0.0);
        while (first < negative.size() && int(negative[first] / size_t(width)) < band - radius) ++first;
        for (size_t n = first; n < negative.size() && int(negative[n] / size_t(width)) < band + rows + radius; ++n) {
            const int x = int(negative[n] % size_t(width)), y = int(negative[n] / size_t(width));
            for (int v = std::max(band, y - radius); v <= std::min(band + rows - 1, y + radius); ++v)
                for (int u = std::max(x0, x - radius); u <= std::min(x1, x + radius); ++u) taken[size_t(v - band) * w + u - x0] += share[n];
        }
        // A share above one (no overshoot within reach) leaves that pixel at zero and the rest of the deficit unpaid.
        for (int v = 0; v < rows; ++v)
            for (int u = 0; u < w; ++u) {
                float& p = pixels[size_t(band + v) * width + u + x0];
                p = float(std::max(0.0f, p) * std::max(0.0, 1.0 - taken[size_t(v) * w + u]));
            }
    }
    return cleared;
}

int ringing_reach(const XrayStats& stats) {
    // Regular splatting's taps are about a voxel apart on its stride-1 grid.
    double widest = std::max(1.0, stats.max_magnification);
    for (double s : stats.strides) widest = std::max(widest, s);
    // At most 32 pixels (magnifications above 16): each negative pixel's window costs its area twice.
    return int(std::ceil(kRingingNodes * std::min(widest, 16.0)));
}

namespace {

/// Whether every voxel of every grid, times its density scale, is >= 0 (from the grids' value ranges, read
/// when they were built or mapped): then every splat is, and so must every pixel be.
bool nonnegative_field(const std::vector<WeightedGrid>& grids) {
    return std::all_of(grids.begin(), grids.end(), [](const WeightedGrid& g) {
        const auto [lo, hi] = g.grid->value_range();
        return g.density_scale >= 0 ? lo >= 0 : hi <= 0;
    });
}

/// The least and most pixels per voxel (least magnified direction) over the boxes of the grids rendered:
/// what regular splatting compensates for, the same for a grid read whole and for its batches (which set
/// XrayParams::compensation_magnification to the whole stream's). {0, 0} when unknown.
std::pair<double, double> regular_compensation_range(const std::vector<const Grid*>& levels, const Camera& cam,
                                                     const XrayParams& params) {
    if (params.compensation_magnification.first > 0) return params.compensation_magnification;
    XrayStats range;
    for (const Grid* g : levels) {
        if (g->active_voxel_count() == 0) continue;
        const auto corners = corner_pixels_per_voxel(g->index_bbox(), g->index_to_world(), cam, VoxelAxis::LeastMagnified);
        if (!corners) return {0.0, 0.0};
        range.include_magnification(corners->first, corners->second);
    }
    return {range.min_magnification, range.max_magnification};
}

ImageAccumulator render_splatted(const std::vector<WeightedGrid>& grids, const Camera& cam, const XrayParams& params,
                                 const Kernel& kernel, PostFilterShape post_shape, RenderControl& control, XrayStats& stats) {
    const bool regular = params.method == XrayMethod::Regular;
    BlockPlanParams plan_params;
    plan_params.kernel_radius = kernel.radius();
    plan_params.fixed_stride = regular ? 1 : params.stride;
    plan_params.margin_nodes = regular ? 0 : PostFilter::kMarginNodes;
    plan_params.nearest_stride = params.method == XrayMethod::BilinearSpread;
    plan_params.fractional_strides = true;
    const double tolerance = geometric_tolerance(params.footprint_tolerance, kernel);
    plan_params.footprint_tolerance = tolerance;

    std::vector<PlannedGrid> planned;
    planned.reserve(grids.size());  // splat params point at their clip regions
    std::map<double, XrayStats> bands;  // the magnifications of the grids splatted at each stride
    bool any_cut = false;
    std::map<double, bool> strides;
    uint64_t planned_blocks = 0;
    std::vector<Grid> levels;
    levels.reserve(grids.size());  // PlannedGrid points into it
    for (const auto& g : grids) {
        // Coarse levels stand for their voxels only where footprints are integrated over pixels.
        const int chosen = g.level > 0 ? 0 : params.level >= 0 ? params.level : params.antialias ? automatic_level(*g.grid, cam) : 0;
        levels.push_back(g.grid->level(chosen));
        const int level = g.level + chosen;
        stats.level = std::max(stats.level, level);
        ViewProjection view(cam, levels.back().index_to_world());
        ClipRegion clip = g.clip ? g.clip->in_index_space(levels.back().index_to_world()) : ClipRegion();
        plan_params.clip = clip.keeps_everything() ? nullptr : &clip;
        BlockPlan plan = plan_blocks(levels.back().blocks(), view, plan_params, &control);
        stats.blocks_total += plan.blocks_total;
        stats.blocks_culled += plan.blocks_culled;
        stats.blocks_clipped += plan.blocks_clipped;
        stats.include_magnification(plan.min_magnification, plan.max_magnification);
        for (const auto& [stride, blocks] : plan.by_stride) {
            strides[stride] = true;
            bands[stride].include_magnification(plan.min_magnification, plan.max_magnification);
            planned_blocks += blocks.size();
        }
        any_cut |= plan_params.clip != nullptr;
        planned.push_back({&g, &levels.back(), level, std::move(view), std::move(clip), std::move(plan)});
    }
    // The image, and for one band at a time a splat grid per worker plus the one they are added into;
    // the finest stride's grid is the largest.
    MemoryBudget budget(params.memory_limit);
    budget.add("image", uint64_t(cam.width()) * cam.height() * sizeof(float));
    if (!strides.empty()) {
        const int workers = tbb::this_task_arena::max_concurrency();
        const double finest = strides.begin()->first;
        std::ostringstream name;
        name << "splat grid at stride " << finest << copies(workers);
        budget.add(name.str(),
                   uint64_t(workers + 1) * SplatGrid::bytes(cam.width(), cam.height(), finest, plan_params.margin_nodes));
    }
    // Each cut grid's splatter of the kernels its cuts cross (src/splat/cut_splat.h). A grid cut by planes
    // seen edge-on renders into an image of its own, which those planes then mask; its voxels are cut by the
    // other planes only: those the edge-on planes cross keep whole footprints.
    std::vector<std::optional<CutSplatter>> cutters(planned.size());
    std::vector<ClipRegion> splat_clips(planned.size());
    size_t masked_grids = 0;
    for (size_t k = 0; k < planned.size(); ++k) {
        if (planned[k].clip.keeps_everything()) continue;
        const CutSplatter& cuts = cutters[k].emplace(planned[k].view, planned[k].clip, kernel);
        splat_clips[k] = cuts.masks() ? cuts.unmasked() : planned[k].clip;
        masked_grids += cuts.masks();
    }
    const uint64_t pixels = uint64_t(cam.width()) * cam.height();
    if (any_cut) budget.add("images of the voxels clip planes cut, one per thread", uint64_t(tbb::this_task_arena::max_concurrency()) * pixels * sizeof(double));
    if (masked_grids > 0 && !strides.empty()) {
        const int workers = tbb::this_task_arena::max_concurrency();
        budget.add("images and splat grids of the grids cut edge-on", masked_grids * (pixels * sizeof(float) +
                   uint64_t(workers + 1) * SplatGrid::bytes(cam.width(), cam.height(), strides.begin()->first, plan_params.margin_nodes)));
    }
    check_memory(budget, cam, stats);
    ImageAccumulator image(cam.width(), cam.height());
    control.begin_phase(planned_blocks, 0.0, 0.97);

    const double range = range_scale(grids);
    const FootprintTable& table = FootprintTable::of(kernel);
    SplatParams splat;
    splat.mode = params.method == XrayMethod::BilinearSpread ? SplatMode::BilinearSpread : SplatMode::Footprint;
    splat.table = &table;
    splat.kernel = &kernel;
    splat.kernel_radius = kernel.radius();
    splat.footprint_tolerance = tolerance;
    splat.antialias = params.antialias;

    // One splat grid per stride (depth band), shared by all grids: X-ray contributions simply add.
    // The voxels a clip plane cuts where their kept footprints have sharp edges are integrated per pixel,
    // straight into the image (or the grid's own, to be masked).
    std::vector<std::vector<CutVoxel>> cut(planned.size());
    std::vector<std::unique_ptr<ImageAccumulator>> masked(planned.size());
    for (size_t k = 0; k < planned.size(); ++k)
        if (cutters[k] && cutters[k]->masks()) masked[k] = std::make_unique<ImageAccumulator>(cam.width(), cam.height());
    std::vector<const Grid*> level_grids;
    for (const Grid& g : levels) level_grids.push_back(&g);
    // Over the grids' boxes, and for a stream's batches the whole stream's: every batch decides as the grid would.
    const std::pair<double, double> box_magnification = regular_compensation_range(level_grids, cam, params);
    splat.phase_tables = box_magnification.first > 0 && box_magnification.second <= kPerspectiveBandRatio * box_magnification.first;
    const Compensation compensation(params, kernel, post_shape, cam, std::move(bands),
                                    regular ? box_magnification : std::pair<double, double>{});
    auto to_image = [&](SplatGrid& grid, ImageAccumulator& out) {
        compensation.apply(grid, control);
        if (regular)
            add_unfiltered(grid, out);
        else
            post_convolve(grid, post_shape, out, control, params.antialias);
    };
    for (const auto& [stride, unused] : strides) {
        SplatGrid target(cam.width(), cam.height(), stride, plan_params.margin_nodes);
        for (size_t k = 0; k < planned.size(); ++k) {
            const PlannedGrid& pg = planned[k];
            auto it = pg.plan.by_stride.find(stride);
            if (it == pg.plan.by_stride.end()) continue;
            splat.density_scale = float(pg.source->density_scale * range);
            splat.level = pg.level;
            splat.clip = splat_clips[k].keeps_everything() ? nullptr : &splat_clips[k];
            splat.cuts = cutters[k] ? &*cutters[k] : nullptr;
            std::optional<SplatGrid> own;
            if (masked[k]) own.emplace(target.zero_like());
            stats.voxels_splatted +=
                splat_blocks(pg.level_grid->blocks(), it->second, pg.view, splat, own ? *own : target, control, &stats.taps, &cut[k]);
            if (own) to_image(*own, *masked[k]);
        }
        to_image(target, image);
        stats.strides.push_back(stride);
    }
    for (size_t k = 0; k < planned.size(); ++k) {
        if (!cutters[k]) continue;
        stats.voxels_cut += cut[k].size();
        stats.taps += cutters[k]->splat(cut[k], masked[k] ? *masked[k] : image, control);
        if (!masked[k]) continue;
        cutters[k]->mask(*masked[k]);
        for (size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] += masked[k]->pixels[i];
    }
    if (range != 1.0) {
        // A power of two: multiplying in float rounds exactly as dividing in double did (once, and
        // only below float's normal range), and vectorises (the division took 4 ms at 1698 x 1715).
        const float unscale = float(1.0 / range);
        for (float& pixel : image.pixels) pixel *= unscale;
    }
    return image;
}

/// The sub-pixels per pixel edge of a zoomed-out view (level_of_detail.h): enough for every grid, where
/// every grid renders from an automatic level 0 and is zoomed out that far; else 1.
int supersampling(const std::vector<WeightedGrid>& grids, const Camera& cam, const XrayParams& params) {
    if (params.supersampling > 0) return params.supersampling;
    if (!may_supersample(params)) return 1;
    int factor = 1;
    uint64_t voxels = 0;
    for (const WeightedGrid& g : grids) {
        if (g.grid->active_voxel_count() == 0) continue;
        voxels += g.grid->active_voxel_count();
        if (g.level > 0 || automatic_level(*g.grid, cam) > 0) return 1;
        const int wanted = automatic_supersampling(g.grid->index_bbox(), g.grid->index_to_world(), cam);
        if (wanted == 1) return 1;
        factor = std::max(factor, wanted);
    }
    return supersampling_that_pays(factor, cam, voxels);
}

/// The mean of every sub x sub block of `fine`.
ImageAccumulator box_averaged(const ImageAccumulator& fine, int sub) {
    ImageAccumulator image(fine.width / sub, fine.height / sub);
    const double inverse_area = 1.0 / (double(sub) * sub);
    std::vector<double> sums(image.width);
    for (int r = 0; r < image.height; ++r) {
        std::fill(sums.begin(), sums.end(), 0.0);
        for (int y = r * sub; y < (r + 1) * sub; ++y) {
            const float* in = fine.pixels.data() + size_t(y) * fine.width;
            for (int c = 0; c < image.width; ++c)
                for (int x = c * sub; x < (c + 1) * sub; ++x) sums[c] += in[x];
        }
        for (int c = 0; c < image.width; ++c) image.pixels[size_t(r) * image.width + c] = float(sums[c] * inverse_area);
    }
    return image;
}

/// A zoomed-out view rendered at sub x sub sub-pixels a pixel, where every voxel spans a sub-pixel or more
/// and is splatted as at magnification 1 (not integrated over pixels one by one, 5 to 7 times the work a
/// voxel), then box-averaged to the pixels. Without the memory for the sub-pixels, the pixels themselves.
ImageAccumulator render_supersampled(const std::vector<WeightedGrid>& grids, const Camera& cam, const XrayParams& params,
                                     const Kernel& kernel, PostFilterShape post_shape, RenderControl& control,
                                     XrayStats& stats, int sub) {
    const Camera fine(cam.world_to_camera(), cam.projection(), cam.width() * sub, cam.height() * sub);
    XrayParams at_level_0 = params;
    at_level_0.level = 0;  // what the pixels chose: the sub-pixels would choose no other
    // A node per sub-pixel: the post filter's fractional strides (1.02 and the like here) lost up to 0.09%
    // of a one-pixel image's mass, stride 1 0.02%. In perspective the sub-pixels are chosen for the least
    // magnified voxels and the others span up to a band more (automatic_supersampling): their own strides keep
    // their footprints in 4 x 4 windows.
    if (at_level_0.stride == 0 && cam.orthographic()) at_level_0.stride = 1;
    const XrayStats before = stats;
    try {
        ImageAccumulator image = box_averaged(render_splatted(grids, fine, at_level_0, kernel, post_shape, control, stats), sub);
        stats.min_magnification /= sub;
        stats.max_magnification /= sub;
        stats.supersampling = sub;
        return image;
    } catch (const OutOfMemory&) {
        stats = before;
        return render_splatted(grids, cam, at_level_0, kernel, post_shape, control, stats);
    }
}

/// The inputs are finite (from_dense refuses others, non-finite voxels of files are skipped, cameras
/// and density scales are checked), so a non-finite pixel is a line integral beyond float's range.
void check_finite(const XrayImage& image, const std::vector<WeightedGrid>& grids) {
    const size_t overflowed = size_t(std::count_if(image.pixels.begin(), image.pixels.end(), [](float p) { return !std::isfinite(p); }));
    if (overflowed == 0) return;
    double largest = 0;
    for (const WeightedGrid& g : grids) {
        const auto [lo, hi] = g.grid->value_range();
        largest = std::max(largest, std::max(std::abs(double(lo)), std::abs(double(hi))) * std::abs(g.density_scale));
    }
    std::ostringstream msg;
    msg << "render_xray: the line integral exceeds float32's range (3.4e38) at " << overflowed << " of "
        << image.pixels.size() << " pixels (densities times density_scale reach " << largest
        << "): scale the densities down with density_scale";
    throw InvalidArgument(msg.str());
}

}  // namespace

XrayImage render_xray(const std::vector<WeightedGrid>& grids_in, const Camera& cam, const XrayParams& params,
                      RenderControl& control, XrayStats* stats_out) {
    const auto start = std::chrono::steady_clock::now();
    // Grids with an attenuation map render as their mapped copies, which live as long as the render.
    std::vector<Grid> mapped;
    mapped.reserve(grids_in.size());
    std::vector<WeightedGrid> grids = grids_in;
    for (WeightedGrid& g : grids)
        if (g.attenuation) {
            mapped.push_back(g.attenuation->apply(*g.grid));
            g.grid = &mapped.back();
            g.attenuation = nullptr;
        }
    // Validate every argument up front, whatever the method, so mistakes are caught early.
    const Kernel kernel = Kernel::from_name(params.splat_kernel);
    const PostFilterShape post_shape = post_filter_from_name(params.post_filter);
    if (params.stride < 0 || params.stride > kMaxStride)
        throw InvalidArgument("stride must be 0 (automatic) or a number of pixels from 1 to " + std::to_string(kMaxStride));
    if (params.threads < 0) throw InvalidArgument("threads must be 0 (all cores) or positive");
    if (params.supersampling < 0) throw InvalidArgument("supersampling must be 0 (automatic) or positive");
    if (params.pixel_step < 1) throw InvalidArgument("pixel_step must be at least 1");
    if (!(params.footprint_tolerance >= 0))
        throw InvalidArgument("footprint_tolerance must be a number >= 0 (infinity: linearised footprints only)");
    if (params.pixel_step > 1 && params.method != XrayMethod::Exact)
        throw InvalidArgument("pixel_step is only supported by method 'exact'");
    for (const WeightedGrid& g : grids)
        if (!std::isfinite(g.density_scale)) throw InvalidArgument("density_scale must be finite");

    XrayStats stats;
    stats.batches = 1;
    stats.nonnegative = nonnegative_field(grids);
    XrayImage out;
    tbb::task_arena arena(params.threads > 0 ? params.threads : tbb::task_arena::automatic);
    arena.execute([&] {
        if (params.method == XrayMethod::Exact) {
            out.width = (cam.width() + params.pixel_step - 1) / params.pixel_step;
            out.height = (cam.height() + params.pixel_step - 1) / params.pixel_step;
            // A double image per worker and their sum, every pixel's ray, and the float result.
            const uint64_t pixels = uint64_t(out.width) * out.height;
            const int workers = tbb::this_task_arena::max_concurrency();
            MemoryBudget budget(params.memory_limit);
            budget.add("image", pixels * sizeof(float));
            budget.add("double image" + copies(workers), uint64_t(workers + 1) * pixels * sizeof(double));
            budget.add("pixel rays", pixels * (2 * sizeof(Vec3) + sizeof(double)));
            check_memory(budget, cam, stats);
            const std::vector<double> px = render_exact_xray(grids, cam, kernel, params.pixel_step, control);
            out.pixels = ZeroedBuffer<float>(px.size());
            std::copy(px.begin(), px.end(), out.pixels.begin());
            for (const auto& g : grids) stats.voxels_splatted += g.grid->active_voxel_count();
            return;
        }
        const int sub = supersampling(grids, cam, params);
        ImageAccumulator image = sub > 1 ? render_supersampled(grids, cam, params, kernel, post_shape, control, stats, sub)
                                         : render_splatted(grids, cam, params, kernel, post_shape, control, stats);
        // The passband compensation rings below zero beside a sharp edge, and so do Catmull-Rom's lobes: a field
        // >= 0 must not (a negative line integral is a transmission above 100%). After the sub-pixels' mean, as a
        // stream's sum of batches is.
        if (params.keep_nonnegative && stats.nonnegative)
            stats.pixels_negative_corrected += clear_negative_pixels(image.pixels, image.width, image.height, ringing_reach(stats));
        out.width = image.width;
        out.height = image.height;
        out.pixels = std::move(image.pixels);
    });
    check_finite(out, grids);
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (stats_out) *stats_out = stats;
    return out;
}

std::pair<double, double> effective_magnification(const Grid& grid, const Camera& camera) {
    const ViewProjection view(camera, grid.index_to_world());
    BlockPlanParams params;
    params.margin_nodes = 0;
    const BlockPlan plan = plan_blocks(grid.blocks(), view, params);
    return {plan.min_magnification, plan.max_magnification};
}

}  // namespace pcvr
