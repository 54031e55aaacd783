/// @file vdb_io.cpp
/// @brief OpenVDB file I/O: read_vdb, list_grids and write_vdb (one grid or several, float or vector).
///
/// Conversions on reading: double, int32, int64, bool and mask grids become float grids (one templated
/// copy); level sets become fog volumes via tools::sdfToFogVolume (1 inside, a linear ramp across the
/// interior half of the narrow band, 0 outside; the grid's metadata records "pcvr_converted_from").
/// Vector, string and point grids are rejected. Reading itself goes through vdb_reader.h, which
/// validates a file before OpenVDB trusts it.
#include "volume/grid_data.h"
#include "volume/vdb_reader.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/ValueTransformer.h>
#include <openvdb/tree/LeafManager.h>

#include <unistd.h>
#include <fcntl.h>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <new>
#include <random>
#include <set>
#include <sstream>

#include "pcvr/errors.h"

namespace pcvr {

namespace vdb = openvdb;
using vdb::io::GridDescriptor;

namespace {

using namespace vdb_reader;

/// The value itself: a scalar grid's whole value.
struct WholeValue {
    template <typename T>
    auto operator()(const T& value) const { return value; }
};

/// A float copy of any scalar grid (or of one component of a vector grid's values, `part`): same topology,
/// tiles, transform and metadata. Throws GridError (prefixed with `context`) for a finite value beyond float's
/// range, which would become infinity.
template <typename SrcGridT, typename Part = WholeValue>
vdb::FloatGrid::Ptr convert_to_float(const SrcGridT& src, const std::string& context, Part part = {}) {
    auto out = vdb::FloatGrid::create(static_cast<float>(part(src.background())));
    static_cast<vdb::MetaMap&>(*out) = static_cast<const vdb::MetaMap&>(src);
    out->setTransform(src.transform().copy());
    std::atomic<bool> overflow{false};
    vdb::tools::transformValues(
        src.cbeginValueOn(), *out, [&overflow, part](const typename SrcGridT::ValueOnCIter& it, auto& acc) {
            const auto source = part(*it);
            const float value = static_cast<float>(source);
            if (std::isinf(value) && std::isfinite(double(source))) overflow = true;
            if (it.isVoxelValue()) {
                acc.setValue(it.getCoord(), value);
            } else {
                vdb::CoordBBox box;
                it.getBoundingBox(box);
                acc.getTree()->fill(box, value, /*active=*/true);
            }
        });
    if (overflow)
        throw GridError(context + " holds values beyond float32's range (3.4e38), in which grids hold densities");
    return out;
}

GridError unsupported_value_type(const std::string& type, const std::string& context) {
    const bool vector = type.rfind("vec", 0) == 0;
    return GridError(context + " has value type " + type +
                     (vector ? ": vector grids are not supported" : ", which is not supported") +
                     " (need a scalar density grid)");
}

/// The grid as a float fog volume, or GridError for value types we cannot render.
vdb::FloatGrid::Ptr to_float_fog(const vdb::GridBase::Ptr& grid, const std::string& context) {
    vdb::FloatGrid::Ptr out = vdb::gridPtrCast<vdb::FloatGrid>(grid);
    if (!out) grid->apply<ConvertibleGrids>([&](const auto& g) { out = convert_to_float(g, context); });
    if (!out) throw unsupported_value_type(grid->valueType(), context);
    if (out->getGridClass() == vdb::GRID_LEVEL_SET) {
        vdb::tools::sdfToFogVolume(*out);  // also sets the class to fog volume
        out->insertMeta("pcvr_converted_from", vdb::StringMetadata("level set"));
    }
    return out;
}

/// io::Archive's stream writer, which io::File calls without checking that the writes succeeded.
class Writer : public vdb::io::Archive {
public:
    explicit Writer(VdbCompression compression) {
        switch (compression) {
            case VdbCompression::Blosc: setCompression(vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ACTIVE_MASK); break;
            case VdbCompression::Zip: setCompression(vdb::io::COMPRESS_ZIP | vdb::io::COMPRESS_ACTIVE_MASK); break;
            case VdbCompression::None: setCompression(vdb::io::COMPRESS_NONE); break;
        }
    }
    void write_to(std::ostream& os, const vdb::GridCPtrVec& grids) const { write(os, grids, /*seekable=*/true); }
};

std::string temp_path_for(const std::string& path) {
    std::random_device rd;
    std::ostringstream s;
    s << path << ".tmp-" << ::getpid() << "-" << std::hex << ((uint64_t(rd()) << 32) | rd());
    return s.str();
}

/// The union of the three float grids' active voxels as one vec3s grid, each voxel (x, y, z) from their values
/// there (a component's background where it has none).
vdb::Vec3SGrid::Ptr combine_components(const std::array<vdb::FloatGrid::ConstPtr, 3>& parts) {
    auto out = vdb::Vec3SGrid::create(vdb::Vec3s(parts[0]->background(), parts[1]->background(), parts[2]->background()));
    for (const auto& part : parts) out->tree().topologyUnion(part->tree());
    out->tree().voxelizeActiveTiles();  // a tile of one component may hold another's voxels
    vdb::tree::LeafManager<vdb::Vec3STree> leaves(out->tree());
    leaves.foreach([&parts](vdb::Vec3STree::LeafNodeType& leaf, size_t) {
        // Accessors cache nodes and are not thread-safe: one set per leaf.
        std::array<vdb::FloatGrid::ConstAccessor, 3> values{parts[0]->getConstAccessor(), parts[1]->getConstAccessor(),
                                                             parts[2]->getConstAccessor()};
        for (auto it = leaf.beginValueOn(); it; ++it) {
            const vdb::Coord c = it.getCoord();
            it.setValue(vdb::Vec3s(values[0].getValue(c), values[1].getValue(c), values[2].getValue(c)));
        }
    });
    return out;
}

/// The OpenVDB grid that write_vdb stores for `grid`: its components' voxels (shared, not copied, for a float
/// grid) under their transform, with the grid's name, metadata and the fog-volume class.
vdb::GridBase::ConstPtr file_grid(const VdbFileGrid& grid, const std::string& prefix) {
    const std::string context = prefix + "grid " + quoted(grid.name);
    if (grid.components.size() != 1 && grid.components.size() != 3)
        throw GridError(context + " has " + std::to_string(grid.components.size()) +
                        " components: a float grid has 1, a vector grid 3");
    const Mat4& index_to_world = grid.components[0].index_to_world();
    for (const Grid& component : grid.components)
        if (std::memcmp(component.index_to_world().m, index_to_world.m, sizeof index_to_world.m) != 0)
            throw GridError(context + ": its components lie under different index-to-world transforms");

    vdb::MetaMap meta;
    for (const auto& [key, value] : grid.metadata) meta.insertMeta(key, vdb::StringMetadata(value));
    meta.insertMeta(vdb::GridBase::META_GRID_NAME, vdb::StringMetadata(grid.name));
    meta.insertMeta(vdb::GridBase::META_GRID_CLASS, vdb::StringMetadata(vdb::GridBase::gridClassToString(vdb::GRID_FOG_VOLUME)));
    meta.insertMeta(vdb::GridBase::META_GRID_CREATOR, vdb::StringMetadata("pcvr"));
    // The Grid's own transform: with_index_to_world may have re-placed it since it was read.
    const detail::VdbTransform xform = detail::to_vdb_transform(index_to_world);
    if (xform.world_scale != 1.0) meta.insertMeta(detail::kWorldScaleMetadata, vdb::DoubleMetadata(xform.world_scale));
    if (grid.components.size() == 1) return grid.components[0].data()->vdb->copyReplacingMetadataAndTransform(meta, xform.transform);
    vdb::Vec3SGrid::Ptr vector = combine_components({grid.components[0].data()->vdb, grid.components[1].data()->vdb,
                                                     grid.components[2].data()->vdb});
    static_cast<vdb::MetaMap&>(*vector) = meta;
    vector->setTransform(xform.transform);
    vector->setVectorType(vdb::VEC_INVARIANT);
    return vector;
}

}  // namespace

Grid read_vdb(const std::string& path, const std::string& grid_name) {
    detail::initialize_openvdb();
    return guard_read(path, [&] {
        Reader reader(path);
        const size_t index = choose_grid(reader, grid_name);
        const std::string name = Reader::display_name(reader.entries()[index]);
        const std::string context = "grid " + quoted(name) + " in " + quoted(path);
        // Check the type before reading voxels: a vector grid is refused without loading it.
        if (!reader.entries()[index].scalar) throw unsupported_value_type(reader.entries()[index].value_type, context);
        vdb::FloatGrid::Ptr grid = to_float_fog(reader.read_grid(index), context);
        return detail::make_grid(grid, path, name, context);
    });
}

std::array<Grid, 3> read_vdb_vector(const std::string& path, const std::string& grid_name) {
    detail::initialize_openvdb();
    return guard_read(path, [&] {
        Reader reader(path);
        const int index = reader.find(grid_name);
        if (index < 0)
            throw GridError(quoted(path) + " has no grid named " + quoted(grid_name) + "; grids in the file: " + grid_list(reader));
        const Entry& entry = reader.entries()[size_t(index)];
        const std::string name = Reader::display_name(entry);
        const std::string context = "grid " + quoted(name) + " in " + quoted(path);
        if (entry.scalar) throw GridError(context + " has value type " + entry.value_type + ", not a vector (need vec3s or vec3d)");
        const vdb::GridBase::Ptr grid = reader.read_grid(size_t(index));
        std::array<vdb::FloatGrid::Ptr, 3> parts;
        grid->apply<vdb::TypeList<vdb::Vec3SGrid, vdb::Vec3DGrid>>([&](const auto& g) {
            for (int c = 0; c < 3; ++c) parts[c] = convert_to_float(g, context, [c](const auto& v) { return v[c]; });
        });
        if (!parts[0]) throw GridError(context + " has value type " + entry.value_type + ", which is not supported (need vec3s or vec3d)");
        return std::array<Grid, 3>{detail::make_grid(parts[0], path, name + ".x", context),
                                   detail::make_grid(parts[1], path, name + ".y", context),
                                   detail::make_grid(parts[2], path, name + ".z", context)};
    });
}

std::vector<GridInfo> list_grids(const std::string& path) {
    detail::initialize_openvdb();
    return guard_read(path, [&] {
        Reader reader(path);
        std::vector<GridInfo> out;
        for (size_t i = 0; i < reader.entries().size(); ++i) {
            const Entry& e = reader.entries()[i];
            GridInfo info;
            info.name = Reader::display_name(e);
            info.value_type = e.value_type;
            vdb::GridBase::Ptr meta = reader.read_grid_metadata(i);
            info.grid_class = vdb::GridBase::gridClassToString(meta->getGridClass());
            for (auto it = meta->beginMeta(); it != meta->endMeta(); ++it)
                if (auto text = dynamic_cast<const vdb::StringMetadata*>(it->second.get()))
                    info.metadata[it->first] = text->value();
            // Writers store the count as statistics metadata; without it, count the voxels, reading
            // only grids whose layout is checked (others, e.g. points, report 0).
            if (e.grid) {
                info.active_voxels = e.grid->activeVoxelCount();
            } else if (auto count = meta->getMetadata<vdb::Int64Metadata>(vdb::GridBase::META_FILE_VOXEL_COUNT)) {
                info.active_voxels = uint64_t(count->value());
            } else if (reader.can_check_layout(e)) {
                info.active_voxels = reader.read_grid(i)->activeVoxelCount();
            }
            out.push_back(std::move(info));
        }
        return out;
    });
}

void Grid::write_vdb(const std::string& path, const std::string& name) const {
    write_vdb(path, name, VdbCompression::Blosc);
}

void Grid::write_vdb(const std::string& path, const std::string& name, VdbCompression compression,
                     const GridMetadata& metadata) const {
    pcvr::write_vdb(path, {VdbFileGrid{name, {*this}, metadata}}, compression);
}

void write_vdb(const std::string& path, const std::vector<VdbFileGrid>& grids, VdbCompression compression) {
    detail::initialize_openvdb();
    const std::string prefix = "cannot write " + quoted(path) + ": ";
    if (grids.empty()) throw GridError(prefix + "no grids to write");
    vdb::GridCPtrVec out;
    std::set<std::string> names;
    for (const VdbFileGrid& grid : grids) {
        if (!names.insert(grid.name).second) throw GridError(prefix + "two grids are named " + quoted(grid.name));
        out.push_back(file_grid(grid, prefix));
    }

    // Write beside the target and rename: readers see the old file or the new one, never half of one.
    const std::string tmp = temp_path_for(path);
    try {
        std::ofstream os;
        os.open(tmp, std::ios::out | std::ios::binary | std::ios::trunc);
        if (!os) throw Error(prefix + "cannot create " + quoted(tmp) + ": " + std::strerror(errno));
        os.exceptions(std::ios::failbit | std::ios::badbit);
        Writer(compression).write_to(os, out);
        os.close();
        // Flush to disk before the rename, so a crash cannot leave an empty file under the old name.
        const int fd = ::open(tmp.c_str(), O_RDONLY);
        if (fd >= 0) {
            ::fsync(fd);
            ::close(fd);
        }
        if (std::rename(tmp.c_str(), path.c_str()) != 0)
            throw Error(prefix + "cannot rename " + quoted(tmp) + " to it: " + std::strerror(errno));
    } catch (const Error&) {
        std::remove(tmp.c_str());
        throw;
    } catch (const std::ios_base::failure&) {
        const int err = errno;
        std::remove(tmp.c_str());
        throw Error(prefix + "write failed" + (err ? std::string(": ") + std::strerror(err) : std::string()));
    } catch (const std::exception& e) {
        std::remove(tmp.c_str());
        throw Error(prefix + e.what());
    }
}

}  // namespace pcvr
