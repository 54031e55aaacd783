// Bindings of the rendering API: Camera, render_xray and small queries. Long calls run with the GIL
// released; Python callbacks (progress, cancel) are polled from the calling thread.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "bindings.h"
#include "pcvr/attenuation_map.h"
#include "pcvr/camera.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/grid_stream.h"
#include "pcvr/kernel.h"
#include "pcvr/memory_budget.h"
#include "pcvr/stride.h"
#include "pcvr/xray.h"
#include "render_call.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace pcvr::python {

namespace {

/// `attenuation`: None, one AttenuationMap for every grid, or a sequence with one map (or None) per grid.
std::vector<const AttenuationMap*> attenuation_from_python(nb::handle attenuation, size_t count) {
    if (attenuation.is_none()) return std::vector<const AttenuationMap*>(count, nullptr);
    if (nb::isinstance<AttenuationMap>(attenuation))
        return std::vector<const AttenuationMap*>(count, nb::cast<const AttenuationMap*>(attenuation));
    std::vector<const AttenuationMap*> out;
    try {
        for (nb::handle item : attenuation) out.push_back(item.is_none() ? nullptr : nb::cast<const AttenuationMap*>(item));
    } catch (const std::exception&) {
        throw nb::type_error("render_xray: attenuation must be None, a pcvr_native.AttenuationMap, or one (or None) per grid");
    }
    if (out.size() != count)
        throw nb::value_error("render_xray: attenuation must be one AttenuationMap or one per grid");
    return out;
}

nb::object render_xray_py(nb::handle grid_arg, const Camera& camera, const std::string& method,
                          const std::string& splat_kernel, const std::string& post_filter, int stride, int threads,
                          nb::handle density_scale, nb::handle progress, nb::handle cancel, nb::handle stats,
                          int pixel_step, double footprint_tolerance, std::optional<uint64_t> memory_limit,
                          bool antialias, nb::handle level, nb::handle attenuation, nb::handle clip_planes, nb::handle clip_box,
                          const std::string& passband) {
    // Grids and streamed grids, in any mix; scales follow the sequence's order.
    const nb::list items = nb::isinstance<Grid>(grid_arg) || nb::isinstance<GridStream>(grid_arg)
                               ? nb::list(nb::make_tuple(grid_arg))
                               : grid_sequence(grid_arg, "render_xray");
    const std::vector<double> scales = scales_from_python(density_scale, items.size(), "render_xray");
    const std::vector<const AttenuationMap*> maps = attenuation_from_python(attenuation, items.size());
    const std::vector<ClipRegion> clips = clip_regions_from_python(clip_planes, clip_box, items.size(), "render_xray");
    std::vector<Grid> grids;
    std::vector<std::shared_ptr<GridStream>> streams;
    std::vector<double> grid_scales, stream_scales;
    std::vector<const AttenuationMap*> grid_maps, stream_maps;
    std::vector<const ClipRegion*> grid_clips, stream_clips;
    auto clip_of = [&](size_t i) { return clips[i].keeps_everything() ? nullptr : &clips[i]; };
    for (size_t i = 0; i < items.size(); ++i) {
        if (nb::isinstance<GridStream>(items[i])) {
            streams.push_back(nb::cast<std::shared_ptr<GridStream>>(items[i]));
            stream_scales.push_back(scales[i]);
            stream_maps.push_back(maps[i]);
            stream_clips.push_back(clip_of(i));
        } else {
            if (!nb::isinstance<Grid>(items[i]))
                throw nb::type_error("render_xray: `grid` must be a pcvr_native.Grid or GridStream, or a sequence of them");
            grids.push_back(nb::cast<Grid>(items[i]));
            grid_scales.push_back(scales[i]);
            grid_maps.push_back(maps[i]);
            grid_clips.push_back(clip_of(i));
        }
    }
    std::vector<WeightedGrid> weighted;
    for (size_t i = 0; i < grids.size(); ++i) weighted.push_back({&grids[i], grid_scales[i], 0, grid_maps[i], grid_clips[i]});
    std::vector<WeightedStream> weighted_streams;
    for (size_t i = 0; i < streams.size(); ++i)
        weighted_streams.push_back({streams[i].get(), stream_scales[i], stream_maps[i], stream_clips[i]});

    XrayParams params;
    params.method = xray_method_from_name(method);
    params.splat_kernel = splat_kernel;
    params.post_filter = post_filter;
    params.stride = stride;
    params.threads = threads;
    params.pixel_step = pixel_step;
    params.footprint_tolerance = footprint_tolerance;
    params.antialias = antialias;
    params.passband = passband_from_name(passband);
    params.level = level_from_python(level, "render_xray");
    if (memory_limit && *memory_limit == 0) throw InvalidArgument("memory_limit must be a positive number of bytes, or None");
    params.memory_limit = memory_limit.value_or(0);

    RenderControl control;
    if (!cancel.is_none() && cancel_requested(cancel)) throw Cancelled("render cancelled before it started");
    XrayImage image;
    XrayStats xs;
    run_polled([&] { image = render_xray(weighted, weighted_streams, camera, params, control, &xs); }, control, progress, cancel);

    if (!stats.is_none()) {
        nb::list strides;
        for (double s : xs.strides) strides.append(s);
        stats["voxels"] = xs.voxels_splatted;
        stats["blocks"] = xs.blocks_total;
        stats["blocks_culled"] = xs.blocks_culled;
        stats["blocks_clipped"] = xs.blocks_clipped;
        stats["voxels_cut"] = xs.voxels_cut;
        stats["magnification"] = xs.min_magnification;
        stats["magnification_max"] = xs.max_magnification;
        stats["strides"] = strides;
        stats["stride"] = xs.strides.empty() ? 0 : xs.strides.front();
        stats["taps"] = xs.taps;
        stats["pixels_negative_corrected"] = xs.pixels_negative_corrected;
        stats["nonnegative"] = xs.nonnegative;
        stats["ringing_reach"] = ringing_reach(xs);
        stats["seconds"] = xs.seconds;
        stats["memory_bytes"] = xs.memory_bytes;
        stats["batches"] = xs.batches;
        stats["level"] = xs.level;
        stats["supersampling"] = xs.supersampling;
    }
    auto* pixels = new ZeroedBuffer<float>(std::move(image.pixels));
    nb::capsule owner(pixels, [](void* p) noexcept { delete static_cast<ZeroedBuffer<float>*>(p); });
    return nb::cast(nb::ndarray<nb::numpy, float, nb::ndim<2>>(
        pixels->data(), {size_t(image.height), size_t(image.width)}, owner));
}

}  // namespace

void bind_render(nb::module_& m) {
    nb::class_<AttenuationMap>(m, "AttenuationMap",
                               "A piecewise-linear map from grid values to linear attenuation per world unit, constant "
                               "beyond its ends, that render_xray applies to every active voxel (a DRR from Hounsfield units).")
        .def(nb::init<std::vector<double>, std::vector<double>>(), "values"_a, "attenuation"_a,
             "Through the points (values[i], attenuation[i]); values strictly increasing.")
        .def_static("hounsfield", &AttenuationMap::hounsfield, "mu_water"_a, "mu_air"_a = 0.0,
                    "mu = mu_water * (1 + HU / 1000), never below mu_air: what DRR tools integrate through a CT.")
        .def_prop_ro("values", &AttenuationMap::values)
        .def_prop_ro("attenuation", &AttenuationMap::attenuation)
        .def("__call__", [](const AttenuationMap& map, double value) { return map(value); }, "value"_a,
             "The attenuation of one value.")
        .def("apply",
             [](const AttenuationMap& map, const Grid& grid) {
                 nb::gil_scoped_release release;
                 return map.apply(grid);
             },
             "grid"_a, "The grid with every active voxel's value mapped (render_xray(attenuation=...) does this per "
                       "render: keep the result to render many views of it).")
        .def("__repr__", [](const AttenuationMap& map) {
            return "<pcvr_native.AttenuationMap of " + std::to_string(map.values().size()) + " points>";
        });

    nb::class_<Camera>(m, "Camera",
                       "A camera in Blender's conventions: world_to_camera (camera looks down -Z) and an OpenGL "
                       "projection matrix, as returned by Object.calc_matrix_camera(depsgraph, x=width, y=height).")
        .def("__init__",
             [](Camera* self, nb::handle world_to_camera, nb::handle projection, int width, int height) {
                 new (self) Camera(mat4_from_python(world_to_camera, "world_to_camera"),
                                   mat4_from_python(projection, "projection"), width, height);
             },
             "world_to_camera"_a, "projection"_a, "width"_a, "height"_a)
        .def_prop_ro("width", &Camera::width)
        .def_prop_ro("height", &Camera::height)
        .def_prop_ro("orthographic", &Camera::orthographic)
        .def_prop_ro("world_to_camera", [](const Camera& c) { return mat4_to_numpy(c.world_to_camera()); })
        .def_prop_ro("projection", [](const Camera& c) { return mat4_to_numpy(c.projection()); })
        .def("__repr__", [](const Camera& c) {
            return std::string("<pcvr_native.Camera ") + (c.orthographic() ? "orthographic " : "perspective ") +
                   std::to_string(c.width()) + "x" + std::to_string(c.height()) + ">";
        });

    m.def("render_xray", &render_xray_py, "grid"_a, "camera"_a, "method"_a = "pcvr", "splat_kernel"_a = "gauss1.4",
          "post_filter"_a = "bilinear", "stride"_a = 0, "threads"_a = 0, nb::kw_only(), "density_scale"_a = 1.0,
          "progress"_a = nb::none(), "cancel"_a = nb::none(), "stats"_a = nb::none(), "pixel_step"_a = 1,
          "footprint_tolerance"_a = kFootprintTolerance, "memory_limit"_a = nb::none(), "antialias"_a = true,
          "level"_a = "auto", "attenuation"_a = nb::none(), "clip_planes"_a = nb::none(), "clip_box"_a = nb::none(),
          "passband"_a = "compensated",
          "X-ray (line integral) image of one grid or a sequence of grids: float32 (height, width), row 0 on top.\n"
          "A GridStream (stream_vdb) stands wherever a Grid may: it is read a batch at a time, and memory_limit\n"
          "then bounds the batch's voxels (half the limit) as well as the buffers (the other half).\n"
          "footprint_tolerance: perspective views splat voxels whose linearised footprint would be off by more\n"
          "than this fraction of its peak with exact per-ray footprints (0: all; inf: none).\n"
          "memory_limit: bytes the render's buffers may take (None: the memory this machine has available);\n"
          "a request beyond it raises MemoryError before anything is allocated, saying what it needs.\n"
          "antialias: footprints of voxels smaller than a pixel are integrated over each pixel's area, so a pixel\n"
          "is the mean of the line integral over it (False: sampled at its centre, as method 'exact' is).\n"
          "level: 'auto' renders each grid from the coarsest level of detail (Grid.level) whose voxels project to at\n"
          "most 1/32 of a pixel (which keeps the image within 0.1% of level 0's), or a level k >= 0 (0: the grid itself); stats['level'] says which.\n"
          "attenuation: an AttenuationMap (or one per grid, None for none) applied to every active voxel before\n"
          "splatting: the image integrates the attenuation, e.g. AttenuationMap.hounsfield(0.0206) for a CT in HU\n"
          "(mu per world unit: 0.0206 per mm, water at 70 keV).\n"
          "passband: 'compensated' sharpens methods 'pcvr' and 'regular' by a small filter that pays back the blur\n"
          "of the splat kernel and the post filter (closer to the sampled signal's line integrals); 'paper' keeps\n"
          "the paper's kernel and post filter as they are. 'bilinear_spread' and 'exact' always render the paper's.\n"
          CLIP_DOC);
    m.def("default_memory_limit", &default_memory_limit,
          "Bytes a render may use when memory_limit is None: the memory this machine (or its cgroup) has available.");

    m.def("clear_negative_pixels",
          [](nb::ndarray<float, nb::ndim<2>, nb::c_contig, nb::device::cpu> image, int reach) {
              if (reach < 0) throw nb::value_error("clear_negative_pixels: reach must be >= 0 pixels");
              const int height = int(image.shape(0)), width = int(image.shape(1));
              nb::gil_scoped_release release;
              return clear_negative_pixels(image.data(), width, height, reach);
          },
          "image"_a, "reach"_a,
          "Clears, in place, the pixels below zero of a float32 (height, width) X-ray of a field >= 0, taking what\n"
          "that adds from the positive pixels within `reach` of each, in proportion to them, as render_xray does to\n"
          "its own image. For images added up from parts rendered apart (each part's stats['nonnegative'] true;\n"
          "reach: the largest of their stats['ringing_reach']). Returns how many pixels were below zero.");
    m.def("kernel_info", [](const std::string& name) {
        const Kernel k = Kernel::from_name(name);
        nb::dict d;
        d["name"] = k.name();
        d["radius"] = k.radius();
        d["variance"] = k.variance();
        d["line_integral_at_centre"] = k.line_integral(0.0);
        return d;
    }, "name"_a, "Radius (voxels), per-axis variance (voxels^2) and central line integral of a splat kernel.");

    m.def("effective_magnification",
          [](const Grid& grid, const Camera& camera) {
              nb::gil_scoped_release release;
              return effective_magnification(grid, camera);
          },
          "grid"_a, "camera"_a, "(min, max) pixels per voxel over the grid's blocks in view; (0, 0) when none is.");
    m.def("effective_magnification",
          [](const GridStream& stream, const Camera& camera) { return effective_magnification(stream, camera); },
          "grid"_a, "camera"_a,
          "A GridStream's (min, max) pixels per voxel over the corners of its active box (its blocks are in its "
          "file); (0, 0) when empty or when a corner is behind the eye.");
    m.def("automatic_stride",
          [](const Grid& grid, const Camera& camera) {
              nb::gil_scoped_release release;
              const auto [lo, hi] = effective_magnification(grid, camera);
              return hi > 0 ? fractional_stride(lo, lo) : 1.0;
          },
          "grid"_a, "camera"_a,
          "The X-ray subgrid stride (pixels between nodes, not necessarily whole) PCVR picks for the least "
          "magnified part of the grid in view (perspective views use coarser strides for nearer depth bands).");
}

}  // namespace pcvr::python
