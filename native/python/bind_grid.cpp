// Python bindings of pcvr/grid.h: Grid, read_vdb, list_grids, write_vdb. Thin: conversions and GIL handling only.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/array.h>
#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <filesystem>
#include <optional>
#include <sstream>

#include "bindings.h"
#include "pcvr/dense_grid_builder.h"
#include "pcvr/errors.h"
#include "pcvr/grid.h"
#include "pcvr/grid_stream.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace pcvr::python {

namespace {

/// numpy's shape tuple as text, e.g. "(4, 4)".
std::string shape_string(nb::handle arr) {
    const nb::tuple shape(arr.attr("shape"));
    std::string s = "(";
    for (size_t i = 0; i < nb::len(shape); ++i) s += (i ? ", " : "") + std::to_string(nb::cast<long long>(shape[i]));
    return s + (nb::len(shape) == 1 ? ",)" : ")");
}

/// A matrix argument of the grid API: ValueError from the conversion becomes GridError, so every
/// bad transform (wrong shape, non-finite, singular) raises the same exception type.
Mat4 grid_matrix(nb::handle obj, const char* what) {
    // The shape is checked here too so its message survives: mat4_from_python formats it with
    // nb::cast<std::string>, which bindings.cpp instantiates without nanobind/stl/string.h (a
    // std::bad_cast; the same ODR clash is why this file avoids nb::cast<std::string>).
    nb::object arr;
    try {
        arr = nb::module_::import_("numpy").attr("asarray")(obj, "dtype"_a = "float64");
    } catch (nb::python_error&) {
        throw GridError(std::string(what) + " must be a 4x4 matrix of numbers");
    }
    const std::string shape = shape_string(arr);
    if (shape != "(4, 4)") throw GridError(std::string(what) + " must have shape (4, 4), got " + shape);
    try {
        return mat4_from_python(arr, what);
    } catch (const nb::builtin_exception& e) {
        throw GridError(e.what());
    }
}

nb::dict grid_info_to_dict(const GridInfo& info) {
    nb::dict d;
    d["name"] = info.name;
    d["value_type"] = info.value_type;
    d["grid_class"] = info.grid_class;
    d["active_voxels"] = info.active_voxels;
    d["metadata"] = info.metadata;
    return d;
}

Grid from_dense(nb::handle values, nb::handle index_to_world, double background, const std::string& name) {
    const Mat4 m = grid_matrix(index_to_world, "index_to_world");
    // numpy does every dtype conversion (ints, float64, bool) and makes a C-order copy only if needed.
    nb::module_ np = nb::module_::import_("numpy");
    nb::object original = np.attr("asarray")(values);
    nb::object arr = np.attr("ascontiguousarray")(original, "dtype"_a = "float32");
    // A finite float64 beyond float32's range arrives as infinity: say what it really is.
    if (!original.attr("dtype").equal(np.attr("dtype")("float32")) &&
        nb::cast<bool>(nb::bool_(np.attr("any")(np.attr("isinf")(arr) & np.attr("isfinite")(original))))) {
        nb::object where = np.attr("argwhere")(np.attr("isinf")(arr) & np.attr("isfinite")(original))[nb::int_(0)].attr("tolist")();
        nb::object value = original.attr("__getitem__")(nb::module_::import_("builtins").attr("tuple")(where));
        throw GridError("Grid.from_dense '" + name + "': value " + nb::str(value).c_str() + " at " + nb::str(where).c_str() +
                        " is beyond float32's range (3.4e38), in which grids hold densities: divide the values "
                        "and multiply density_scale instead");
    }
    if (nb::cast<int>(arr.attr("ndim")) != 3)
        throw InvalidArgument("Grid.from_dense: values must be a 3-D array indexed [i, j, k], got shape " +
                              shape_string(arr));
    auto view = nb::cast<nb::ndarray<const float, nb::ndim<3>, nb::c_contig, nb::device::cpu>>(arr);
    const std::array<size_t, 3> shape{view.shape(0), view.shape(1), view.shape(2)};
    // `arr` keeps the buffer alive while the GIL is released.
    nb::gil_scoped_release release;
    return Grid::from_dense(view.data(), shape, m, float(background), name);
}

/// Grid.from_slabs: numpy converts each slab (as from_dense does); the planes are copied without the GIL.
Grid from_slabs(nb::handle slabs, std::array<size_t, 3> shape, nb::handle index_to_world, double background,
                const std::string& name) {
    const Mat4 m = grid_matrix(index_to_world, "index_to_world");
    std::optional<DenseGridBuilder> builder;
    {
        nb::gil_scoped_release release;
        builder.emplace(shape, m, float(background), name, "Grid.from_slabs");
    }
    nb::module_ np = nb::module_::import_("numpy");
    for (nb::handle slab : nb::iter(slabs)) {
        nb::object arr = np.attr("ascontiguousarray")(slab, "dtype"_a = "float32");
        const size_t ndim = nb::cast<size_t>(arr.attr("ndim"));
        if (ndim != 3 || nb::cast<size_t>(arr.attr("shape")[1]) != shape[1] ||
            nb::cast<size_t>(arr.attr("shape")[2]) != shape[2])
            throw InvalidArgument("Grid.from_slabs: each slab must be indexed [i, j, k] with " +
                                  std::to_string(shape[1]) + " x " + std::to_string(shape[2]) +
                                  " voxels per plane, got shape " + shape_string(arr));
        auto view = nb::cast<nb::ndarray<const float, nb::ndim<3>, nb::c_contig, nb::device::cpu>>(arr);
        nb::gil_scoped_release release;
        builder->add_planes(view.data(), view.shape(0));
    }
    nb::gil_scoped_release release;
    return builder->finish();
}

VdbCompression compression_from_string(const std::string& s) {
    if (s == "blosc") return VdbCompression::Blosc;
    if (s == "zip") return VdbCompression::Zip;
    if (s == "none") return VdbCompression::None;
    throw InvalidArgument("write_vdb: compression must be 'blosc', 'zip' or 'none', got '" + s + "'");
}

/// pcvr::write_vdb without the GIL; failures to write are I/O errors: OSError rather than pcvr::Error's
/// RuntimeError (GridError, for what cannot be written, stays itself).
void write_file(const std::filesystem::path& path, const std::vector<VdbFileGrid>& grids, VdbCompression codec) {
    std::string error;
    {
        nb::gil_scoped_release release;
        try {
            write_vdb(path.string(), grids, codec);
        } catch (const GridError&) {
            throw;
        } catch (const Error& e) {
            error = e.what();
        }
    }
    if (!error.empty()) {
        PyErr_SetString(PyExc_OSError, error.c_str());
        throw nb::python_error();
    }
}

/// write_vdb's {name: Grid or (x, y, z) Grids} and {name: {str: str}} as the grids of a file.
std::vector<VdbFileGrid> file_grids(const nb::dict& grids, const nb::dict& metadata) {
    std::vector<VdbFileGrid> out;
    for (auto [key, value] : grids) {
        VdbFileGrid grid;
        grid.name = nb::cast<std::string>(key);
        if (nb::isinstance<Grid>(value)) {
            grid.components = {nb::cast<Grid>(value)};
        } else {
            std::vector<nb::handle> parts;
            for (nb::handle part : nb::iter(value)) parts.push_back(part);
            for (nb::handle part : parts)
                if (!nb::isinstance<Grid>(part) || parts.size() != 3)
                    throw nb::type_error(("write_vdb: grid '" + grid.name +
                                          "' must be a Grid or a sequence of three Grids (x, y, z)").c_str());
            for (nb::handle part : parts) grid.components.push_back(nb::cast<Grid>(part));
        }
        if (metadata.contains(key)) grid.metadata = nb::cast<GridMetadata>(metadata[key]);
        out.push_back(std::move(grid));
    }
    for (auto [key, value] : metadata)
        if (!grids.contains(key))
            throw InvalidArgument("write_vdb: metadata names grid '" + nb::cast<std::string>(key) + "', which is not written");
    return out;
}

/// The active voxels over index_bbox, read through blocks() exactly as the renderer sees them.
nb::object to_dense(const Grid& g, float fill) {
    const auto b = g.index_bbox();
    std::array<size_t, 3> dims{0, 0, 0};
    if (g.active_voxel_count() > 0)
        for (int a = 0; a < 3; ++a) dims[a] = size_t(int64_t(b[a + 3]) - int64_t(b[a]) + 1);
    const uint64_t total = uint64_t(dims[0]) * dims[1] * dims[2];
    if (total > (uint64_t(1) << 31))
        throw InvalidArgument("Grid.to_dense: the active bounding box holds " + std::to_string(total) +
                              " voxels, too many for a dense array");
    auto* data = new float[std::max<uint64_t>(total, 1)];
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<float*>(p); });
    {
        nb::gil_scoped_release release;
        std::fill(data, data + total, fill);
        for (const VoxelBlock& block : g.blocks())
            for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
                if (!block.active(offset)) continue;
                const int64_t i = int64_t(block.origin[0]) + (offset >> 6) - b[0];
                const int64_t j = int64_t(block.origin[1]) + ((offset >> 3) & 7) - b[1];
                const int64_t k = int64_t(block.origin[2]) + (offset & 7) - b[2];
                data[(size_t(i) * dims[1] + size_t(j)) * dims[2] + size_t(k)] = block.value(offset);
            }
    }
    return nb::cast(nb::ndarray<nb::numpy, float, nb::ndim<3>>(data, {dims[0], dims[1], dims[2]}, owner));
}

LevelReduction level_reduction_from_name(const std::string& name, const std::string& function) {
    if (name == "mean_over_zero") return LevelReduction::MeanOverZero;
    if (name == "mean_over_background") return LevelReduction::MeanOverBackground;
    if (name == "max_over_background") return LevelReduction::MaxOverBackground;
    throw InvalidArgument(function + ": reduction must be 'mean_over_zero' (the X-ray's levels), "
                                     "'mean_over_background' (render_shaded's) or 'max_over_background' (render_mip's)");
}

/// An inclusive index box as ((i0, j0, k0), (i1, j1, k1)).
nb::tuple bbox_tuple(const std::array<int32_t, 6>& b) {
    return nb::make_tuple(nb::make_tuple(b[0], b[1], b[2]), nb::make_tuple(b[3], b[4], b[5]));
}

std::string grid_repr(const Grid& g) {
    std::ostringstream s;
    const auto b = g.index_bbox();
    const auto r = g.value_range();
    s << "<pcvr_native.Grid '" << g.name() << "': " << g.active_voxel_count() << " active voxels, index bbox ("
      << b[0] << ", " << b[1] << ", " << b[2] << ")..(" << b[3] << ", " << b[4] << ", " << b[5] << "), values ["
      << r.first << ", " << r.second << "]";
    if (!g.source_path().empty()) s << ", from '" << g.source_path() << "'";
    s << ">";
    return s.str();
}

}  // namespace

void bind_grid(nb::module_& m) {
    nb::class_<Grid>(m, "Grid",
                     "A scalar OpenVDB volume (float voxels, sparse). Immutable; copies share their voxels.")
        .def_static("from_dense", &from_dense, "values"_a, "index_to_world"_a, "background"_a = 0.0,
                    "name"_a = "density",
                    "Build from a 3-D array indexed [i, j, k] (converted to float32). Voxels equal to\n"
                    "`background` stay inactive. `index_to_world` is a 4x4 matrix, world = M @ [i, j, k, 1].\n"
                    "A singular or non-finite matrix, or NaN or infinite values, raise GridError.")
        .def_static("from_slabs", &from_slabs, "slabs"_a, "shape"_a, "index_to_world"_a, "background"_a = 0.0,
                    "name"_a = "density",
                    "Build as from_dense from an iterable of slabs of i-planes, in order, each indexed [i, j, k]\n"
                    "with shape[1] x shape[2] voxels per plane: only the sparse grid and one slab are held.\n"
                    "Raises GridError unless the slabs hold exactly shape[0] planes.")
        .def(
            "write_vdb",
            [](const Grid& g, const std::filesystem::path& path, const std::string& name, const std::string& compression,
               const GridMetadata& metadata) {
                write_file(path, {VdbFileGrid{name, {g}, metadata}}, compression_from_string(compression));
            },
            "path"_a, "name"_a = "density", "compression"_a = "blosc", "metadata"_a = GridMetadata(),
            "Write as a float fog-volume grid called `name`, compressed with 'blosc', 'zip' or 'none',\n"
            "with `metadata` (a dict of str) as the grid's string metadata.\n"
            "The file is replaced atomically (written beside it, then renamed); on failure an OSError\n"
            "is raised and no partial file is left.")
        .def(
            "with_index_to_world",
            [](const Grid& g, nb::handle matrix) { return g.with_index_to_world(grid_matrix(matrix, "index_to_world")); },
            "index_to_world"_a, "The same voxels (shared, not copied) under another index-to-world matrix.")
        .def_prop_ro("index_to_world", [](const Grid& g) { return mat4_to_numpy(g.index_to_world()); },
                     "(4, 4) float64 array: world = M @ [i, j, k, 1], voxel centres at integer indices.")
        .def_prop_ro("active_voxel_count", &Grid::active_voxel_count)
        .def_prop_ro("index_bbox", [](const Grid& g) { return bbox_tuple(g.index_bbox()); },
                     "Inclusive index bounds of the active voxels: ((i0, j0, k0), (i1, j1, k1)); zeros when empty.")
        .def_prop_ro(
            "value_range",
            [](const Grid& g) {
                const auto r = g.value_range();
                return nb::make_tuple(double(r.first), double(r.second));
            },
            "(min, max) over the active voxels; (0, 0) when empty.")
        .def_prop_ro("background", &Grid::background,
                     "The value of inactive voxels; shaded and MIP renders reconstruct towards it beyond the active ones.")
        .def_prop_ro("name", &Grid::name)
        .def("level",
             [](const Grid& g, int k, const std::string& reduction) {
                 return g.level(k, level_reduction_from_name(reduction, "Grid.level"));
             },
             "k"_a, "reduction"_a = "mean_over_zero",
             "Level of detail k (0: this grid): each voxel stands for 2 x 2 x 2 voxels of the level before, at their "
             "centre (index_to_world scaled by 2 per level and moved by half a voxel), and is active where any of them "
             "is: their mean with inactive ones counting as 0 ('mean_over_zero': the X-ray's levels, which keep line "
             "integrals) or as the background ('mean_over_background': render_shaded's), or their largest value with "
             "inactive ones counting as the background ('max_over_background': render_mip's). Cached with the voxels.")
        .def_prop_ro(
            "source_path",
            [](const Grid& g) -> std::optional<std::string> {
                if (g.source_path().empty()) return std::nullopt;
                return g.source_path();
            },
            "The file the grid was read from, None for grids built in memory.")
        .def_prop_ro(
            "block_count",
            [](const Grid& g) {
                nb::gil_scoped_release release;  // the first call builds the block list
                return g.blocks().size();
            },
            "Number of 8^3 voxel blocks the renderer walks (leaves plus expanded active tiles).")
        .def("to_dense", &to_dense, "fill"_a = 0.0f,
             "The active voxels as a float32 array indexed [i - i0, j - j0, k - k0] over index_bbox\n"
             "((i0, j0, k0) = index_bbox[0]); voxels that are not active hold `fill`. Read through the\n"
             "same 8^3 blocks the renderer walks. Raises ValueError above 2^31 voxels.")
        .def("__repr__", &grid_repr);

    m.def(
        "write_vdb",
        [](const std::filesystem::path& path, const nb::dict& grids, const std::string& compression,
           std::optional<nb::dict> metadata) {
            write_file(path, file_grids(grids, metadata.value_or(nb::dict())), compression_from_string(compression));
        },
        "path"_a, "grids"_a, "compression"_a = "blosc", "metadata"_a = nb::none(),
        "Write several grids into one .vdb file, in the dict's order: {name: Grid} a float grid, {name: (x, y, z)}\n"
        "a vec3s grid from three Grids under one index_to_world (on the union of their active voxels), as\n"
        "simulation caches hold 'density', 'flame' and 'color'. metadata: {name: {str: str}}, per grid.\n"
        "Every grid is a fog volume. The file is replaced atomically, as Grid.write_vdb does; GridError for\n"
        "a repeated name or components under different transforms, OSError when writing fails.");
    m.def(
        "read_vdb_vector",
        [](const std::filesystem::path& path, const std::string& grid) {
            nb::gil_scoped_release release;
            const std::array<Grid, 3> parts = read_vdb_vector(path.string(), grid);
            nb::gil_scoped_acquire acquire;
            return nb::make_tuple(parts[0], parts[1], parts[2]);
        },
        "path"_a, "grid"_a,
        "Read a vector grid (vec3s or vec3d) of a .vdb file as a tuple of three float Grids, its x, y and z\n"
        "components (named 'NAME.x', ...), on the same voxels: e.g. a smoke simulation's 'color', for\n"
        "render_shaded's albedo_grids. Raises as read_vdb, and GridError when the grid is not a vector.");
    m.def(
        "read_vdb",
        [](const std::filesystem::path& path, std::optional<std::string> grid) {
            nb::gil_scoped_release release;
            return read_vdb(path.string(), grid.value_or(""));
        },
        "path"_a, "grid"_a = nb::none(),
        "Read one grid of a .vdb file as a float Grid. grid=None: 'density' if present, else the first\n"
        "float grid. Double and integer grids are converted to float, level sets to fog volumes.\n"
        "Raises FileNotFoundError, VDBReadError (not a VDB, truncated, corrupt) or GridError (unknown\n"
        "grid, vector grid, frustum transform).");
    nb::class_<GridStream>(m, "GridStream",
                           "A grid left in its .vdb file (stream_vdb): render_xray reads it a batch of 128^3 regions at a\n"
                           "time, so memory stays bounded whatever the file's size.")
        .def_prop_ro("name", &GridStream::name)
        .def_prop_ro("path", &GridStream::path)
        .def_prop_ro("index_to_world", [](const GridStream& s) { return mat4_to_numpy(s.index_to_world()); })
        .def_prop_ro("background", &GridStream::background)
        .def_prop_ro("active_voxel_count", &GridStream::active_voxel_count)
        .def_prop_ro("index_bbox", [](const GridStream& s) { return bbox_tuple(s.index_bbox()); },
                     "Inclusive index bounds of the active voxels, as Grid.index_bbox.")
        .def(
            "with_index_to_world",
            [](const GridStream& s, nb::handle matrix) { return s.with_index_to_world(grid_matrix(matrix, "index_to_world")); },
            "index_to_world"_a, "The same stream (file, topology) under another index-to-world matrix.")
        .def_prop_ro(
            "value_range",
            [](const GridStream& s) {
                std::pair<float, float> r;
                {
                    nb::gil_scoped_release release;  // the first call reads the file
                    r = s.value_range();
                }
                return nb::make_tuple(double(r.first), double(r.second));
            },
            "(min, max) over the active voxels, as Grid.value_range; the first call reads the whole file.")
        .def_prop_ro("batch_bytes", [](const GridStream& s) -> std::optional<uint64_t> {
            if (s.batch_bytes() == 0) return std::nullopt;
            return s.batch_bytes();
        })
        .def(
            "level",
            [](const GridStream& s, int k, const std::string& reduction) {
                const LevelReduction r = level_reduction_from_name(reduction, "GridStream.level");
                nb::gil_scoped_release release;  // the first call for a level reads the file
                return s.level(k, r);
            },
            "k"_a, "reduction"_a = "mean_over_zero",
            "Level of detail k, 1 <= k <= 7, as Grid.level(k, reduction) of the grid read whole: made by reading "
            "every batch once, then kept with the stream. render_xray renders a zoomed-out view of a stream from "
            "it when it takes no more than a batch; render_shaded and render_mip take it as a grid.")
        .def("batch_count", &GridStream::batch_count, "batch_bytes"_a,
             "How many batches render_xray reads the stream in at `batch_bytes` a batch (from the topology alone).")
        .def("with_batches", &GridStream::with_batches, "batches"_a, "batch_bytes"_a,
             "The same stream restricted to some of its batches of `batch_bytes` (indices below batch_count): "
             "render_xray renders only those (never a coarse level), so renders of disjoint shares sum to the "
             "whole stream's image, batch by batch.")
        .def_prop_ro("only_batches", &GridStream::only_batches, "The batches with_batches chose; [] for all.")
        .def_prop_ro("leaf_count", &GridStream::leaf_count)
        .def_prop_ro("value_bytes", &GridStream::value_bytes, "Bytes the voxel values would take read whole.")
        .def("__repr__", [](const GridStream& s) {
            std::ostringstream out;
            out << "<pcvr_native.GridStream '" << s.name() << "': " << s.active_voxel_count() << " active voxels in "
                << s.leaf_count() << " leaves, from '" << s.path() << "'>";
            return out.str();
        });
    m.def(
        "stream_vdb",
        [](const std::filesystem::path& path, std::optional<std::string> grid, std::optional<uint64_t> batch_bytes) {
            if (batch_bytes && *batch_bytes == 0) throw InvalidArgument("stream_vdb: batch_bytes must be positive, or None");
            nb::gil_scoped_release release;
            return GridStream::open(path.string(), grid.value_or(""), batch_bytes.value_or(0));
        },
        "path"_a, "grid"_a = nb::none(), "batch_bytes"_a = nb::none(),
        "Open one grid of a .vdb file without reading its values: a GridStream, which render_xray takes in\n"
        "place of a Grid and reads a batch of whole 128^3 regions at a time. batch_bytes: the values a batch\n"
        "may hold (a region alone may hold more: up to 8 MiB); None: half of render_xray's\n"
        "memory_limit, or 64 MiB without one. The file's layout is checked now, as read_vdb does. Float fog\n"
        "volumes only: other grids raise GridError (read them with read_vdb).");
    m.def(
        "list_grids",
        [](const std::filesystem::path& path) {
            std::vector<GridInfo> infos;
            {
                nb::gil_scoped_release release;
                infos = list_grids(path.string());
            }
            nb::list out;
            for (const GridInfo& info : infos) out.append(grid_info_to_dict(info));
            return out;
        },
        "path"_a, "The grids of a .vdb file: a list of dicts with name, value_type, grid_class, active_voxels\n"
        "and metadata (the grid's string metadata).");
}

}  // namespace pcvr::python
