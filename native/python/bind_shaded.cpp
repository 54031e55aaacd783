// Bindings of shaded rendering and MIP: TransferFunction, Light, Shading, render_shaded, render_mip.
// Thin: conversions, GIL handling and the statistics dictionary.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <array>
#include <optional>
#include <vector>

#include "bindings.h"
#include "pcvr/errors.h"
#include "pcvr/shaded.h"
#include "render_call.h"

namespace nb = nanobind;
using namespace nb::literals;

#define SHADOW_DOC                                                                                        \
    "shadow: None (render_shaded's `shadows` decides), True or False (this light casts shadows or not,\n" \
    "whatever render_shaded says)."

#define BRICKS_DOC                                                                                                \
    "A GridStream (stream_vdb) renders in bricks of voxels, each read from the file with the margin its\n"        \
    "kernels reach, front to back, as large as memory_limit lets the render's working set be (the image, the\n" \
    "threads' tile buffers, one brick's values and what is built over them; refused, naming the least that\n"   \
    "serves, where even bricks of 16^3 voxels do not fit) and, with brick_bytes, of at most that many bytes of\n" \
    "values (None: 64 MiB where no memory_limit is given). The image equals the grid's read whole to within\n"   \
    "float rounding (stats['batches']: bricks read, stats['memory_bytes']: the most the render held at once as\n" \
    "counted). Not with shadows, ambient occlusion, albedo_grids or method 'raycast'. brick_share=(k, n): only\n" \
    "share k of n of the bricks in visibility order; the shares' images composited front to back in k's order\n" \
    "(over; MIP: maximum) make the whole image."

namespace pcvr::python {

namespace {

Vec3 vec3_from_python(nb::handle obj, const char* what) {
    nb::object arr = nb::module_::import_("numpy").attr("asarray")(obj, "dtype"_a = "float64");
    if (nb::cast<int>(arr.attr("size")) != 3) throw InvalidArgument(std::string(what) + " must have three numbers");
    nb::object flat = arr.attr("reshape")(3);
    return {nb::cast<double>(flat[nb::int_(0)]), nb::cast<double>(flat[nb::int_(1)]), nb::cast<double>(flat[nb::int_(2)])};
}

nb::tuple vec3_to_python(const Vec3& v) { return nb::make_tuple(v.x, v.y, v.z); }

/// A flag that must be True or False (None too where `none_allowed`): Python's truthiness would turn a
/// misspelt value ("no", 0.5, a numpy array) into a setting without a word.
std::optional<bool> flag_from_python(nb::handle value, const char* what, bool none_allowed) {
    if (none_allowed && value.is_none()) return std::nullopt;
    if (!PyBool_Check(value.ptr()))
        throw nb::type_error((std::string(what) + " must be True or False" + (none_allowed ? " or None" : "") + " (got " +
                              nb::cast<std::string>(nb::repr(value)) + ")").c_str());
    return value.ptr() == Py_True;
}

/// A sun (vector: its direction of travel) or a point light (vector: its position), checked.
Light make_light(Light::Kind kind, nb::handle vector, nb::handle color, double strength, nb::handle shadow, double angle = 0.0) {
    const bool sun = kind == Light::Kind::Sun;
    Light light{kind, vec3_from_python(vector, sun ? "direction" : "position"), vec3_from_python(color, "color"), strength};
    light.angle = angle;
    const std::optional<bool> casts = flag_from_python(shadow, sun ? "Light.sun: shadow" : "Light.point: shadow", true);
    light.shadow = !casts ? Light::Shadow::Default : *casts ? Light::Shadow::On : Light::Shadow::Off;
    Lighting{{light}, {0, 0, 0}, {}}.validate();
    return light;
}

Shading::Model shading_model_from_name(const std::string& name) {
    if (name == "blinn_phong") return Shading::Model::BlinnPhong;
    if (name == "scatter") return Shading::Model::Scatter;
    throw InvalidArgument("Shading: unknown model '" + name + "' (expected blinn_phong or scatter)");
}

/// A sequence of numbers (None: none) as doubles.
std::vector<double> doubles_from_python(nb::handle values) {
    std::vector<double> out;
    if (values.is_none()) return out;
    nb::object flat = nb::module_::import_("numpy").attr("asarray")(values, "dtype"_a = "float64").attr("reshape")(-1);
    for (size_t i = 0, n = nb::len(flat); i < n; ++i) out.push_back(nb::cast<double>(flat[nb::int_(i)]));
    return out;
}

nb::list doubles_to_python(const std::vector<double>& values) {
    nb::list out;
    for (double v : values) out.append(v);
    return out;
}

/// Rows of `columns` numbers (None: no rows), named in the error as `what`.
template <size_t columns>
std::vector<std::array<double, columns>> rows_from_python(nb::handle values, const char* what) {
    std::vector<std::array<double, columns>> out;
    if (values.is_none()) return out;
    nb::object a = nb::module_::import_("numpy").attr("asarray")(values, "dtype"_a = "float64");
    if (nb::cast<size_t>(a.attr("size")) == 0) return out;
    if (nb::cast<int>(a.attr("ndim")) != 2 || nb::cast<size_t>(a.attr("shape")[nb::int_(1)]) != columns)
        throw InvalidArgument(std::string("TransferFunction: ") + what);
    const size_t rows = nb::cast<size_t>(a.attr("shape")[nb::int_(0)]);
    for (size_t i = 0; i < rows; ++i) {
        nb::object row = a[nb::int_(i)];
        std::array<double, columns> r;
        for (size_t c = 0; c < columns; ++c) r[c] = nb::cast<double>(row[nb::int_(c)]);
        out.push_back(r);
    }
    return out;
}

template <size_t columns>
nb::list rows_to_python(const std::vector<std::array<double, columns>>& rows) {
    nb::list out;
    for (const auto& r : rows) {
        nb::object row = nb::steal(PyTuple_New(Py_ssize_t(columns)));
        for (size_t c = 0; c < columns; ++c) PyTuple_SET_ITEM(row.ptr(), Py_ssize_t(c), PyFloat_FromDouble(r[c]));
        out.append(row);
    }
    return out;
}

TransferFunction make_transfer_function(nb::handle density, nb::handle rgba, std::optional<double> unit_distance, nb::handle gradient,
                                        nb::handle gradient_opacity, nb::handle emission) {
    TransferFunction tf;
    tf.density = doubles_from_python(density);
    tf.rgba = rows_from_python<4>(rgba, "rgba must be a list of [r, g, b, a] rows");
    if (tf.rgba.empty()) throw InvalidArgument("TransferFunction: rgba must be a list of [r, g, b, a] rows");
    tf.emission = rows_from_python<3>(emission, "emission must be a list of [r, g, b] rows (one per density)");
    tf.unit_distance = unit_distance.value_or(0.0);
    if (unit_distance && !(*unit_distance > 0)) throw InvalidArgument("TransferFunction: unit_distance must be positive or None");
    tf.gradient = doubles_from_python(gradient);
    tf.gradient_opacity = doubles_from_python(gradient_opacity);
    tf.validate();
    return tf;
}

/// The common arguments of render_shaded and render_mip.
struct CallParts {
    std::vector<Grid> grids;
    std::shared_ptr<GridStream> stream;  ///< instead of grids: rendered in bricks
    BrickedParams bricked;
    std::vector<double> scales;
    ShadedParams params;

    size_t count() const { return stream ? 1 : grids.size(); }
    const Grid* grid(size_t i) const { return stream ? nullptr : &grids[i]; }
};

/// A GridStream's memory_limit and brick_bytes (None: no limit, bricks of the default batch) and brick_share
/// ((k, n): share k of n), refused for Grids.
void bricked_from_python(CallParts& parts, nb::handle memory_limit, nb::handle brick_bytes, nb::handle brick_share,
                         const char* function) {
    const std::string name(function);
    if (!parts.stream && (!memory_limit.is_none() || !brick_bytes.is_none() || !brick_share.is_none()))
        throw InvalidArgument(name + ": memory_limit, brick_bytes and brick_share are for a GridStream (stream_vdb); Grids are in "
                              "memory already");
    for (auto [arg, into, what] : {std::tuple{memory_limit, &parts.bricked.memory_limit, "memory_limit"},
                                   std::tuple{brick_bytes, &parts.bricked.brick_bytes, "brick_bytes"}}) {
        if (arg.is_none()) continue;
        const int64_t bytes = nb::cast<int64_t>(arg);
        if (bytes <= 0) throw InvalidArgument(name + ": " + what + " must be a positive number of bytes, or None");
        *into = uint64_t(bytes);
    }
    if (!brick_share.is_none()) {
        const std::vector<int64_t> share = nb::cast<std::vector<int64_t>>(brick_share);
        if (share.size() != 2 || share[0] < 0 || share[1] < 1 || share[0] >= share[1])
            throw InvalidArgument(name + ": brick_share must be (k, n) with 0 <= k < n");
        parts.bricked.share = size_t(share[0]), parts.bricked.shares = size_t(share[1]);
    }
}

CallParts call_parts(nb::handle grid_arg, nb::handle density_scale, const char* function, const std::string& method,
                     const std::string& splat_kernel, const std::string& post_filter, int stride, double sheet_spacing,
                     double opacity_cutoff, int threads, int tile_size, int pixel_step, int samples_per_sheet, bool cull_transparent,
                     nb::handle level) {
    CallParts parts;
    nb::handle only = grid_arg;
    if (!nb::isinstance<GridStream>(grid_arg) && !nb::isinstance<Grid>(grid_arg) && nb::hasattr(grid_arg, "__len__") &&
        nb::len(grid_arg) == 1)
        only = grid_arg[0];  // [stream]
    if (nb::isinstance<GridStream>(only)) {
        parts.stream = nb::cast<std::shared_ptr<GridStream>>(only);
    } else if (!nb::isinstance<Grid>(grid_arg)) {
        for (nb::handle item : grid_sequence(grid_arg, function))
            if (nb::isinstance<GridStream>(item))
                throw nb::type_error((std::string(function) + ": a GridStream renders alone, in bricks, not with other grids").c_str());
        parts.grids = grids_from_python(grid_arg, function);
    } else {
        parts.grids = grids_from_python(grid_arg, function);
    }
    parts.scales = scales_from_python(density_scale, parts.count(), function);
    ShadedParams& p = parts.params;
    p.method = shaded_method_from_name(method);
    p.splat_kernel = splat_kernel;
    p.post_filter = post_filter;
    p.stride = stride;
    p.sheet_spacing = sheet_spacing;
    p.opacity_cutoff = opacity_cutoff;
    p.threads = threads;
    p.tile_size = tile_size;
    p.pixel_step = pixel_step;
    p.samples_per_sheet = samples_per_sheet;
    p.cull_transparent = cull_transparent;
    p.level = level_from_python(level, function);
    return parts;
}

/// render_shaded's albedo_grids: None, one (red, green, blue) triple of Grids for a single grid, or one entry per
/// grid (None or a triple). The Grids are copied into `held` (handles sharing the voxels), which the volumes
/// point into.
void albedo_grids_from_python(nb::handle arg, std::vector<ShadedVolume>& volumes, std::vector<Grid>& held) {
    if (arg.is_none()) return;
    std::vector<nb::object> entries;
    for (nb::handle item : arg) entries.push_back(nb::borrow(item));
    if (!entries.empty() && nb::isinstance<Grid>(entries.front())) entries = {nb::borrow(arg)};  // one grid's triple
    if (entries.size() != volumes.size())
        throw nb::value_error("render_shaded: albedo_grids must be (red, green, blue) Grids, or one such triple or None per grid");
    held.reserve(3 * entries.size());
    for (size_t i = 0; i < entries.size(); ++i) {
        if (entries[i].is_none()) continue;
        size_t channel = 0;
        for (nb::handle g : entries[i]) {
            if (channel == 3 || !nb::isinstance<Grid>(g))
                throw nb::value_error("render_shaded: each entry of albedo_grids must be three Grids (red, green, blue) or None");
            held.push_back(nb::cast<Grid>(g));
            volumes[i].albedo_grids[channel++] = &held.back();
        }
        if (channel != 3) throw nb::value_error("render_shaded: each entry of albedo_grids must be three Grids (red, green, blue) or None");
    }
}

void fill_stats(nb::handle stats, const ShadedStats& s) {
    if (stats.is_none()) return;
    nb::list strides;
    for (int v : s.strides) strides.append(v);
    nb::list sampled_strides;
    for (int v : s.sampled_strides) sampled_strides.append(v);
    stats["blocks"] = s.blocks_total;
    stats["blocks_outside"] = s.blocks_outside;
    stats["blocks_clipped"] = s.blocks_clipped;
    stats["blocks_transparent"] = s.blocks_transparent;
    stats["bricks_transparent"] = s.bricks_transparent;
    stats["voxels_transparent"] = s.voxels_transparent;
    stats["blocks_listed"] = s.blocks_listed;
    stats["blocks_linearised"] = s.blocks_linearised;
    stats["sheet_metric"] = s.sheets_in_voxel_metric ? "voxels" : "world";
    stats["voxels"] = s.voxels_splatted;
    stats["voxels_occluded"] = s.voxels_occluded;
    stats["taps"] = s.taps;
    stats["samples_classified"] = s.samples_classified;
    stats["samples_shaded"] = s.samples_shaded;
    stats["sheets"] = s.sheets;
    stats["tiles"] = s.tiles;
    stats["tile_size"] = s.tile_size;
    stats["tiles_terminated"] = s.tiles_terminated;
    stats["tile_sheets_composited"] = s.tile_sheets_composited;
    stats["tile_sheets_skipped"] = s.tile_sheets_skipped;
    stats["grids_sampled"] = s.grids_sampled;
    stats["sheet_samples"] = s.sheet_samples;
    stats["sheet_samples_skipped"] = s.sheet_samples_skipped;
    stats["brick_visibility_built"] = s.brick_visibility_built;
    stats["brick_visibility_reused"] = s.brick_visibility_reused;
    stats["strides"] = strides;
    stats["sampled_strides"] = sampled_strides;
    stats["level"] = s.level;
    stats["seconds"] = s.seconds;
    stats["seconds_plan"] = s.seconds_plan;
    stats["seconds_splat"] = s.seconds_splat;
    stats["seconds_post_convolution"] = s.seconds_post_convolution;
    stats["seconds_sampling"] = s.seconds_sampling;
    stats["seconds_shading"] = s.seconds_shading;
    stats["classification"] = s.classification;
    stats["scattering_octaves"] = s.scattering_octaves;
    stats["preintegration_tables_built"] = s.preintegration_tables_built;
    stats["preintegration_table_bytes"] = s.preintegration_table_bytes;
    stats["shadow_texels"] = s.shadow_texels;
    stats["seconds_shadows"] = s.seconds_shadows;
    stats["batches"] = s.batches;
    stats["memory_bytes"] = s.memory_bytes;
}

template <class Image>
nb::object image_to_numpy(Image&& image, int channels) {
    auto* pixels = new ZeroedBuffer<float>(std::move(image.pixels));
    nb::capsule owner(pixels, [](void* p) noexcept { delete static_cast<ZeroedBuffer<float>*>(p); });
    if (channels == 1)
        return nb::cast(nb::ndarray<nb::numpy, float, nb::ndim<2>>(pixels->data(), {size_t(image.height), size_t(image.width)}, owner));
    return nb::cast(nb::ndarray<nb::numpy, float, nb::ndim<3>>(
        pixels->data(), {size_t(image.height), size_t(image.width), size_t(channels)}, owner));
}

nb::object render_shaded_py(nb::handle grid_arg, const Camera& camera, nb::handle transfer_functions, nb::handle lights,
                            nb::handle ambient, nb::handle shading, const std::string& method,
                            const std::string& splat_kernel, const std::string& post_filter, int stride,
                            double sheet_spacing, double opacity_cutoff, int threads, nb::handle progress,
                            nb::handle cancel, nb::handle stats, nb::handle density_scale, int tile_size, int pixel_step,
                            int samples_per_sheet, bool cull_transparent, bool return_depth, nb::handle level,
                            nb::handle clip_planes, nb::handle clip_box, nb::handle shadows, nb::handle albedo_grids,
                            const std::string& sheet_fill, const std::string& classification, nb::handle memory_limit,
                            nb::handle brick_share, int paths, uint64_t seed, nb::handle brick_bytes) {
    CallParts parts = call_parts(grid_arg, density_scale, "render_shaded", method, splat_kernel, post_filter, stride,
                                 sheet_spacing, opacity_cutoff, threads, tile_size, pixel_step, samples_per_sheet, cull_transparent,
                                 level);
    std::vector<TransferFunction> tfs;
    if (nb::isinstance<TransferFunction>(transfer_functions)) {
        tfs.assign(parts.count(), nb::cast<TransferFunction>(transfer_functions));
    } else {
        for (nb::handle item : transfer_functions) tfs.push_back(nb::cast<TransferFunction>(item));
        if (tfs.size() != parts.count())
            throw nb::value_error("render_shaded: transfer_functions must be one TransferFunction or one per grid");
    }
    Lighting lighting;
    if (!lights.is_none())
        for (nb::handle item : lights) lighting.lights.push_back(nb::cast<Light>(item));
    lighting.ambient = vec3_from_python(ambient, "ambient");
    // One material for every grid (None: the default Shading), or one each.
    std::vector<Shading> materials;
    if (shading.is_none()) {
        lighting.material = Shading{};
    } else if (nb::isinstance<Shading>(shading)) {
        lighting.material = nb::cast<Shading>(shading);
    } else {
        for (nb::handle item : shading) materials.push_back(nb::cast<Shading>(item));
        if (materials.size() != parts.count())
            throw nb::value_error("render_shaded: shading must be one Shading or one per grid");
    }

    const std::vector<ClipRegion> clips = clip_regions_from_python(clip_planes, clip_box, parts.count(), "render_shaded");
    bricked_from_python(parts, memory_limit, brick_bytes, brick_share, "render_shaded");
    std::vector<ShadedVolume> volumes;
    for (size_t i = 0; i < parts.count(); ++i)
        volumes.push_back({parts.grid(i), &tfs[i], parts.scales[i], materials.empty() ? nullptr : &materials[i], &clips[i]});
    std::vector<Grid> albedo;
    albedo_grids_from_python(albedo_grids, volumes, albedo);
    RenderControl control;
    if (!cancel.is_none() && cancel_requested(cancel)) throw Cancelled("render cancelled before it started");
    RgbaImage image;
    ShadedStats s;
    parts.params.depth = return_depth;
    parts.params.shadows = *flag_from_python(shadows, "render_shaded: shadows", false);
    parts.params.sheet_fill = sheet_fill_from_name(sheet_fill);
    parts.params.classification = classification_from_name(classification);
    if (paths < 0 || (paths > 0 && parts.params.method != ShadedMethod::Raycast))
        throw nb::value_error("render_shaded: paths must be >= 0, and > 0 only with method='raycast'");
    parts.params.paths = paths;
    parts.params.seed = seed;
    run_polled([&] {
        image = parts.stream ? render_shaded(*parts.stream, volumes[0], camera, lighting, parts.params, parts.bricked, control, &s)
                             : render_shaded(volumes, camera, lighting, parts.params, control, &s);
    }, control, progress, cancel);
    fill_stats(stats, s);
    if (!return_depth) return image_to_numpy(std::move(image), 4);
    MipImage depth;
    depth.width = image.width;
    depth.height = image.height;
    depth.pixels = std::move(image.depth);
    nb::object rgba = image_to_numpy(std::move(image), 4);
    return nb::make_tuple(rgba, image_to_numpy(std::move(depth), 1));
}

nb::object render_mip_py(nb::handle grid_arg, const Camera& camera, const std::string& method, const std::string& splat_kernel,
                         const std::string& post_filter, int stride, double sheet_spacing, int threads, nb::handle progress,
                         nb::handle cancel, nb::handle stats, nb::handle density_scale, int tile_size, int pixel_step,
                         nb::handle level, nb::handle clip_planes, nb::handle clip_box, nb::handle memory_limit, nb::handle brick_share,
                         nb::handle brick_bytes) {
    CallParts parts = call_parts(grid_arg, density_scale, "render_mip", method, splat_kernel, post_filter, stride,
                                 sheet_spacing, 1.0, threads, tile_size, pixel_step, 1, false, level);
    const std::vector<ClipRegion> clips = clip_regions_from_python(clip_planes, clip_box, parts.count(), "render_mip");
    bricked_from_python(parts, memory_limit, brick_bytes, brick_share, "render_mip");
    std::vector<ShadedVolume> volumes;
    for (size_t i = 0; i < parts.count(); ++i) volumes.push_back({parts.grid(i), nullptr, parts.scales[i], nullptr, &clips[i]});
    RenderControl control;
    if (!cancel.is_none() && cancel_requested(cancel)) throw Cancelled("render cancelled before it started");
    MipImage image;
    ShadedStats s;
    run_polled([&] {
        image = parts.stream ? render_mip(*parts.stream, volumes[0], camera, parts.params, parts.bricked, control, &s)
                             : render_mip(volumes, camera, parts.params, control, &s);
    }, control, progress, cancel);
    fill_stats(stats, s);
    return image_to_numpy(std::move(image), 1);
}

}  // namespace

void bind_shaded(nb::module_& m) {
    nb::class_<TransferFunction>(m, "TransferFunction",
                                 "Density -> colour and opacity: piecewise linear over increasing control points. Colours are\n"
                                 "linear RGB; an opacity is that of a slab `unit_distance` world units thick (None: the\n"
                                 "grid's smallest voxel spacing), corrected for each sample's actual thickness.\n"
                                 "gradient and gradient_opacity (both or neither): increasing magnitudes of the density's\n"
                                 "gradient (density units per world unit) and factors in [0, 1], piecewise linear, the end\n"
                                 "values beyond the ends. A sample's opacity a becomes a * factor(|gradient|) before the\n"
                                 "correction, as if the transfer function said a * factor there (VTK's gradient opacity).\n"
                                 "emission (optional): one linear-RGB [r, g, b] per density, piecewise linear like rgba: the\n"
                                 "radiance emitted per world unit of ray, added whether or not the sample absorbs (a sample\n"
                                 "of extinction sigma over a length L sends e (1 - exp(-sigma L)) / sigma forward; e L at sigma 0).")
        .def("__init__",
             [](TransferFunction* self, nb::handle density, nb::handle rgba, std::optional<double> unit_distance, nb::handle gradient,
                nb::handle gradient_opacity, nb::handle emission) {
                 new (self) TransferFunction(make_transfer_function(density, rgba, unit_distance, gradient, gradient_opacity, emission));
             },
             "density"_a, "rgba"_a, "unit_distance"_a = nb::none(), "gradient"_a = nb::none(), "gradient_opacity"_a = nb::none(),
             "emission"_a = nb::none())
        .def_prop_ro("density", [](const TransferFunction& tf) { return doubles_to_python(tf.density); })
        .def_prop_ro("gradient", [](const TransferFunction& tf) { return doubles_to_python(tf.gradient); })
        .def_prop_ro("gradient_opacity", [](const TransferFunction& tf) { return doubles_to_python(tf.gradient_opacity); })
        .def_prop_ro("rgba", [](const TransferFunction& tf) { return rows_to_python(tf.rgba); })
        .def_prop_ro("emission", [](const TransferFunction& tf) { return rows_to_python(tf.emission); })
        .def_prop_ro("unit_distance", [](const TransferFunction& tf) -> std::optional<double> {
            if (tf.unit_distance > 0) return tf.unit_distance;
            return std::nullopt;
        })
        .def("__repr__", [](const TransferFunction& tf) {
            return "<pcvr_native.TransferFunction " + std::to_string(tf.density.size()) + " points over [" +
                   std::to_string(tf.density.front()) + ", " + std::to_string(tf.density.back()) + "]>";
        });

    nb::class_<Light>(m, "Light", "A light for render_shaded: Light.sun(...) or Light.point(...).")
        .def_static(
            "sun",
            [](nb::handle direction, nb::handle color, double strength, nb::handle shadow, double angle) {
                return make_light(Light::Kind::Sun, direction, color, strength, shadow, angle);
            },
            "direction"_a, "color"_a = nb::make_tuple(1.0, 1.0, 1.0), "strength"_a = 1.0, "shadow"_a = nb::none(),
            "angle"_a = 0.0,
            "Parallel light travelling along `direction` (world space) of `strength` E: a white diffuse surface\n"
            "facing it shows E, so its irradiance is pi E, which scattering media receive; `angle`: the\n"
            "angular diameter of its disc in radians (Blender's sun Angle), which softens its shadows.\n" SHADOW_DOC)
        .def_static(
            "point",
            [](nb::handle position, nb::handle color, double strength, nb::handle shadow) {
                return make_light(Light::Kind::Point, position, color, strength, shadow);
            },
            "position"_a, "color"_a = nb::make_tuple(1.0, 1.0, 1.0), "strength"_a = 1.0, "shadow"_a = nb::none(),
            "Point light at `position` (world space): as a sun of strength / distance^2.\n" SHADOW_DOC)
        .def_prop_ro("kind", [](const Light& l) { return l.kind == Light::Kind::Sun ? "sun" : "point"; })
        .def_prop_ro("vector", [](const Light& l) { return vec3_to_python(l.vector); },
                     "The sun's direction of travel, or the point light's position.")
        .def_prop_ro("color", [](const Light& l) { return vec3_to_python(l.color); })
        .def_prop_ro("strength", [](const Light& l) { return l.strength; })
        .def_prop_ro("angle", [](const Light& l) { return l.angle; }, "A sun's angular diameter (radians); 0: hard shadows.")
        .def_prop_ro("shadow", [](const Light& l) -> std::optional<bool> {
            if (l.shadow == Light::Shadow::Default) return std::nullopt;
            return l.shadow == Light::Shadow::On;
        }, "None: as render_shaded's `shadows` says; True or False: this light's own choice.")
        .def("__repr__", [](const Light& l) {
            return std::string("<pcvr_native.Light ") + (l.kind == Light::Kind::Sun ? "sun" : "point") +
                   " strength " + std::to_string(l.strength) + ">";
        });

    nb::class_<Shading>(m, "Shading",
                        "Material of render_shaded: model 'blinn_phong' (two-sided, as in VTK and 3D Slicer: ambient,\n"
                        "diffuse, specular, shininess) or 'scatter' (single scattering, Blender's Principled Volume: the\n"
                        "transfer function's colour is the albedo, lit by the ambient colour and by each light through a\n"
                        "Henyey-Greenstein phase function of `anisotropy` g in (-1, 1), > 0 forwards).")
        .def("__init__",
             [](Shading* self, double ambient, double diffuse, double specular, double shininess, bool lit, const std::string& model,
                double anisotropy, bool ambient_occlusion, int scattering_octaves) {
                 new (self) Shading{ambient, diffuse, specular, shininess, lit, shading_model_from_name(model), anisotropy,
                                    ambient_occlusion, scattering_octaves};
                 Lighting{{}, {0, 0, 0}, *self}.validate();
             },
             "ambient"_a = 0.1, "diffuse"_a = 0.9, "specular"_a = 0.2, "shininess"_a = 10.0, "lit"_a = true,
             "model"_a = "blinn_phong", "anisotropy"_a = 0.0, "ambient_occlusion"_a = false, "scattering_octaves"_a = 6,
             "lit=False: samples keep the transfer function's colours (shading off, as in VTK and 3D Slicer).\n"
             "ambient_occlusion=True: the ambient light reaches each sample through the volumes, as the mean of its\n"
             "transmittance towards +-x, +-y and +-z (the world's light in Cycles is shadowed so).\n"
             "scattering_octaves (model 'scatter'): light scattered more than once, as octaves of shadows at lower\n"
             "extinction (Wrenninge 2015; lights that cast shadows, and the ambient light with ambient_occlusion);\n"
             "1: single scattering only. stats['scattering_octaves'] says how many a render built.")
        .def_rw("ambient", &Shading::ambient)
        .def_rw("diffuse", &Shading::diffuse)
        .def_rw("specular", &Shading::specular)
        .def_rw("shininess", &Shading::shininess)
        .def_rw("lit", &Shading::lit)
        .def_rw("ambient_occlusion", &Shading::ambient_occlusion)
        .def_prop_rw("scattering_octaves", [](const Shading& s) { return s.scattering_octaves; },
                     [](Shading& s, int n) {
                         Shading changed = s;
                         changed.scattering_octaves = n;
                         Lighting{{}, {0, 0, 0}, changed}.validate();
                         s = changed;
                     })
        .def_prop_ro("model", [](const Shading& s) { return s.model == Shading::Model::Scatter ? "scatter" : "blinn_phong"; })
        .def_prop_ro("anisotropy", [](const Shading& s) { return s.anisotropy; })
        .def("__repr__", [](const Shading& s) {
            if (!s.lit) return std::string("<pcvr_native.Shading unlit>");
            if (s.model == Shading::Model::Scatter) return "<pcvr_native.Shading scatter anisotropy " + std::to_string(s.anisotropy) + ">";
            return "<pcvr_native.Shading ambient " + std::to_string(s.ambient) + " diffuse " + std::to_string(s.diffuse) +
                   " specular " + std::to_string(s.specular) + " shininess " + std::to_string(s.shininess) + ">";
        });

    m.def("render_shaded", &render_shaded_py, "grids"_a, "camera"_a, "transfer_functions"_a, "lights"_a = nb::tuple(),
          "ambient"_a = nb::make_tuple(0.1, 0.1, 0.1), "shading"_a = nb::none(), "method"_a = "pcvr",
          "splat_kernel"_a = "gauss1.4", "post_filter"_a = "catmull_rom", "stride"_a = 0, "sheet_spacing"_a = 1.0,
          "opacity_cutoff"_a = 0.99, "threads"_a = 0, "progress"_a = nb::none(), "cancel"_a = nb::none(),
          "stats"_a = nb::none(), nb::kw_only(), "density_scale"_a = 1.0, "tile_size"_a = 0, "pixel_step"_a = 1,
          "samples_per_sheet"_a = 2, "cull_transparent"_a = true, "return_depth"_a = false, "level"_a = 0,
          "clip_planes"_a = nb::none(), "clip_box"_a = nb::none(), nb::arg("shadows").none() = false, "albedo_grids"_a = nb::none(),
          "sheet_fill"_a = "auto", "classification"_a = "auto", "memory_limit"_a = nb::none(), "brick_share"_a = nb::none(),
          "paths"_a = 0, "seed"_a = 0, "brick_bytes"_a = nb::none(),
          "Shaded volume rendering (image-aligned sheet-buffered splatting): float32 (height, width, 4)\n"
          "premultiplied linear RGBA, row 0 on top, alpha 0 where nothing was hit. With return_depth, a\n"
          "tuple (rgba, depth): depth (camera units along the view axis) where opacity first reached 0.5,\n"
          "inf where it never did. transfer_functions and shading: one for every grid, or one per grid (shading\n"
          "None: Shading()'s defaults).\n"
          "level: the level of detail (Grid.level(k, 'mean_over_background')) every grid is rendered from, sheets\n"
          "sheet_spacing of its voxels apart; 'auto': each grid's coarsest level whose voxels project small enough\n"
          "to leave the image as level 0's; stats['level'] says which.\n" CLIP_DOC
          " Samples count for the share of their stretch of ray inside; cut faces are lit by the plane's normal.\n"
          "shadows: lights whose `shadow` is None reach each sample through the volumes (every grid, its transfer\n"
          "function and clip region), attenuated by exp(-optical depth); a light's own shadow=True/False wins.\n"
          "method='raycast' marches a shadow ray per sample; the others read a transmittance volume per light\n"
          "built once per render (stats['shadow_texels'], stats['seconds_shadows']).\n"
          "albedo_grids: a colour per voxel that multiplies the transfer function's (Blender's Color Attribute):\n"
          "(red, green, blue) Grids on the grid's own voxels (the same index_to_world), or one such triple or None\n"
          "per grid. Each sample's factor is the colour of the voxels around it weighted by their density.\n"
          "sheet_fill: 'auto' samples a grid's sheets instead of splatting them where method 'pcvr' splats all of it\n"
          "at stride 1 (stats['grids_sampled'], stats['sheet_samples'], stats['seconds_sampling']); 'splat' never\n"
          "does; 'sample' does for every grid that fits (method 'pcvr' only). A sheet on which a voxel spans two\n"
          "pixels or more is sampled at a subgrid of that stride and post-convolved (stats['sampled_strides']).\n"
          "classification: 'point' classifies each sample by the transfer function at its density; 'preintegrated'\n"
          "each stretch between consecutive samples by the transfer function's mean over its two ends' densities\n"
          "(Engel, Kraus and Ertl 2001: no rings where a sharp transfer function meets the sheets), from a table\n"
          "built once per TransferFunction and kept with it; 'auto' the measured better (stats['classification'],\n"
          "stats['preintegration_tables_built'], stats['preintegration_table_bytes']). The ray caster samples points.\n"
          "paths (method='raycast'): > 0 path-traces scattering media instead (Monte Carlo, light scattered any number\n"
          "of times, every light shadowed, the world's light occluded), that many paths per pixel from `seed`: the\n"
          "brute-force reference for Shading.scattering_octaves.\n" BRICKS_DOC);
    m.def("render_mip", &render_mip_py, "grids"_a, "camera"_a, "method"_a = "pcvr", "splat_kernel"_a = "gauss1.4",
          "post_filter"_a = "catmull_rom", "stride"_a = 0, "sheet_spacing"_a = 1.0, "threads"_a = 0,
          "progress"_a = nb::none(), "cancel"_a = nb::none(), "stats"_a = nb::none(), nb::kw_only(),
          "density_scale"_a = 1.0, "tile_size"_a = 0, "pixel_step"_a = 1, "level"_a = 0, "clip_planes"_a = nb::none(),
          "clip_box"_a = nb::none(), "memory_limit"_a = nb::none(), "brick_share"_a = nb::none(), "brick_bytes"_a = nb::none(),
          "Maximum intensity projection over the same sheets: float32 (height, width), the largest\n"
          "reconstructed density along each ray, never below the largest grid background\n"
          "(times its density_scale; 0 for fog volumes), which a ray that meets no voxel returns.\n"
          "level: as in render_shaded, from levels of maxima (Grid.level(k, 'max_over_background')).\n" CLIP_DOC
          " A sample counts where its point lies inside.\n" BRICKS_DOC);
}

}  // namespace pcvr::python
