/// @file vdb_reader.h
/// @brief A VDB file reader that validates the file before OpenVDB trusts it (private to vdb_io.cpp).
///
/// Files are read with io::Archive's stream-level primitives rather than io::File, because io::File
/// does not notice short reads (a truncated uncompressed grid comes back silently zero-filled) and
/// OpenVDB trusts the sizes stored in a file (a corrupt one can overflow a heap buffer). Here
///   - the input stream throws on the first short read,
///   - every grid descriptor's offsets must lie inside the file, and each grid must end exactly at
///     its descriptor's end offset,
///   - length fields that OpenVDB would allocate from blindly (strings, metadata sizes) are checked
///     against the bytes left in the file before OpenVDB reads them,
///   - a grid's nodes are walked, checking every chunk size, before OpenVDB reads them.
/// Nothing is delay-loaded: a grid that reads without error is complete in memory, so a bad file fails
/// here, never later inside the renderer. Every failure becomes a pcvr exception naming the file.
///
/// | file                 | concern                                                              |
/// |----------------------|----------------------------------------------------------------------|
/// | vdb_stream.h         | the file's stream and size: reads that never trust a stored length   |
/// | vdb_layout_check.h   | validation of metadata, transforms and every node's chunk sizes      |
/// | vdb_delayed_load.h   | validation of OpenVDB's delayed-load table (PCVR never delay-loads)  |
/// | vdb_reader.h (this)  | the table of contents, whole grids, and a stream's topology          |
/// | vdb_leaf_reader.h    | decoding a stream's leaves on all threads                            |
#pragma once

#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/openvdb.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <new>
#include <sstream>
#include <string>
#include <vector>

#include "pcvr/errors.h"
#include "volume/vdb_layout_check.h"
#include "volume/vdb_stream.h"

namespace pcvr::vdb_reader {

/// Value types we turn into float grids; FloatGrid itself needs no conversion.
using ConvertibleGrids = vdb::TypeList<vdb::DoubleGrid, vdb::Int32Grid, vdb::Int64Grid, vdb::BoolGrid, vdb::MaskGrid>;

inline bool is_scalar(const vdb::GridBase& grid) {
    return grid.isType<vdb::FloatGrid>() || grid.apply<ConvertibleGrids>([](const auto&) {});
}

/// One grid in a file's table of contents.
struct Entry {
    GridDescriptor gd;
    std::string value_type;      ///< "float", "vec3s", ...
    bool scalar = false;         ///< float or convertible to float
    vdb::GridBase::Ptr grid;     ///< set only for files without grid offsets, which are read whole
};

/// A VDB file opened for reading. Derives from io::Archive only to reach its protected stream-level
/// readers (header, grid count, grid), which io::File wraps without checking the stream.
/// Not thread-safe (one stream): each read_vdb / list_grids call opens its own Reader.
class Reader : public vdb::io::Archive {
public:
    explicit Reader(const std::string& path) {
        file_.path = path;
        namespace fs = std::filesystem;
        std::error_code ec;
        const fs::file_status status = fs::status(path, ec);
        if (status.type() == fs::file_type::not_found) throw FileNotFound("VDB file not found: " + quoted(path));
        if (ec) throw VdbReadError("cannot read " + quoted(path) + ": " + ec.message());
        if (fs::is_directory(status)) throw VdbReadError("cannot read " + quoted(path) + ": is a directory");
        // Devices and pipes have no size to check against (and a FIFO would block).
        if (!fs::is_regular_file(status)) throw VdbReadError("cannot read " + quoted(path) + ": not a regular file");

        file_.is.open(path, std::ios::in | std::ios::binary);
        if (!file_.is) throw VdbReadError("cannot open " + quoted(path) + ": " + std::strerror(errno));
        file_.is.seekg(0, std::ios::end);
        file_.size = int64_t(file_.is.tellg());
        file_.is.seekg(0);
        // From here on a short read throws std::ios_base::failure instead of yielding garbage.
        file_.is.exceptions(std::ios::failbit | std::ios::badbit);

        if (file_.size < 8) file_.corrupt("too short to be a VDB file (" + std::to_string(file_.size) + " bytes)");
        read_header();  // throws "not a VDB file" on a wrong magic number
        // Tag the stream with the header's versions and compression, as io::File::open does.
        file_.meta = std::make_shared<vdb::io::StreamMetadata>();
        file_.meta->setSeekable(true);
        vdb::io::setStreamMetadataPtr(file_.is, file_.meta, /*transfer=*/false);
        setFormatVersion(file_.is);
        setLibraryVersion(file_.is);
        setDataCompression(file_.is);
        check_.version = fileVersion();

        check_.check_metamap("file metadata");
        vdb::MetaMap().readMeta(file_.is);

        const int32_t count = readGridCount(file_.is);
        // A descriptor takes at least 3 string lengths and 3 offsets.
        if (count < 0 || int64_t(count) * 36 > file_.remaining()) file_.corrupt("invalid grid count " + std::to_string(count));
        entries_.reserve(size_t(count));
        for (int32_t i = 0; i < count; ++i) {
            Entry e;
            if (fileVersion() >= vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING)
                file_.check_strings(3, "grid descriptor");
            else
                file_.check_strings(2, "grid descriptor");
            const vdb::GridBase::Ptr empty = e.gd.read(file_.is);  // throws on unregistered grid types
            e.value_type = empty->valueType();
            e.scalar = is_scalar(*empty);
            if (inputHasGridOffsets()) {
                const int64_t here = file_.tell();
                if (e.gd.getGridPos() < here || e.gd.getEndPos() < e.gd.getGridPos())
                    file_.corrupt("invalid offsets for grid " + quoted(display_name(e)));
                if (e.gd.getEndPos() > file_.size)
                    file_.corrupt("truncated: grid " + quoted(display_name(e)) + " ends at byte " +
                                  std::to_string(e.gd.getEndPos()) + " but the file has " +
                                  std::to_string(file_.size) + " bytes");
                e.gd.seekToEnd(file_.is);
            } else {
                // Written as a stream (io::Stream): no offsets, so grids can only be read in order;
                // an instance's parent comes before it.
                e.grid = read_at_current(e);
                if (e.gd.isInstance()) e.grid->setTree(instance_parent(e)->baseTreePtr());
            }
            entries_.push_back(std::move(e));
        }
    }

    const std::string& path() const { return file_.path; }
    /// The open file, for reading a stream's leaves (vdb_leaf_reader.h).
    const SizedStream& file() const { return file_; }
    const std::vector<Entry>& entries() const { return entries_; }

    /// "name", or "name[N]" for the N-th of several grids sharing a name (OpenVDB's convention);
    /// invalid UTF-8 replaced.
    static std::string display_name(const Entry& e) {
        return valid_utf8(GridDescriptor::nameAsString(e.gd.uniqueName()));
    }

    /// Index of the grid called `name` ("name" or "name[N]", as stored or as display_name shows it), or -1.
    int find(const std::string& name) const {
        const std::string unique = GridDescriptor::stringAsUniqueName(name);
        for (size_t i = 0; i < entries_.size(); ++i)
            if (entries_[i].gd.uniqueName() == unique || display_name(entries_[i]) == name) return int(i);
        for (size_t i = 0; i < entries_.size(); ++i)  // first of several grids with that name
            if (entries_[i].gd.gridName() == name || valid_utf8(entries_[i].gd.gridName()) == name) return int(i);
        return -1;
    }

    /// The grid with its voxels. Instances (grids sharing another grid's tree) get their parent's tree.
    vdb::GridBase::Ptr read_grid(size_t index, size_t depth = 0) {
        const Entry& e = entries_.at(index);
        if (e.grid) return e.grid;
        e.gd.seekToGrid(file_.is);
        vdb::GridBase::Ptr grid = read_at_current(e);
        if (e.gd.isInstance()) grid->setTree(instance_parent(e, depth)->baseTreePtr());
        return grid;
    }

    /// A float grid's metadata, transform and topology, its leaves without values (about 100 bytes
    /// each), after the same checks as read_grid; and where each leaf's record starts in the file, in
    /// the tree's leaf order, for read_leaves. For grid_stream.cpp: float fog volumes with their own
    /// tree (file format 223 or later) only; anything else throws GridError saying to read it whole.
    struct Topology {
        vdb::FloatGrid::Ptr grid;
        std::vector<int64_t> leaf_positions;
    };
    Topology read_topology(size_t index) {
        const Entry& e = entries_.at(index);
        const std::string context = "grid " + quoted(display_name(e)) + " in " + vdb_reader::quoted(file_.path);
        if (e.grid || e.gd.isInstance() || e.gd.gridType() != vdb::FloatTree::treeType() ||
            fileVersion() < vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING)
            throw GridError(context + " cannot be read a part at a time (only float grids with a tree of their own, "
                                      "from OpenVDB 3 or later, can): read it whole");
        e.gd.seekToGrid(file_.is);
        const int64_t start = file_.tell();
        check_.check_grid_header();
        check_.check_affine_map(display_name(e));
        Topology out;
        const int64_t end = check_layout(e, &out.leaf_positions);
        check_grid_end(e, end);
        file_.is.seekg(start);
        readGridCompression(file_.is);
        out.grid = vdb::FloatGrid::create();
        out.grid->setSaveFloatAsHalf(e.gd.saveFloatAsHalf());
        out.grid->readMeta(file_.is);
        if (out.grid->getGridClass() == vdb::GRID_LEVEL_SET)
            throw GridError(context + " is a level set, which is converted to a fog volume as a whole: read it whole");
        vdb::io::setGridClass(file_.is, out.grid->getGridClass());
        out.grid->readTransform(file_.is);
        out.grid->readTopology(file_.is);
        // Leaves whose inactive values were left out of the file take the background.
        vdb::io::setGridBackgroundValuePtr(file_.is, &out.grid->tree().background());
        if (out.leaf_positions.size() != out.grid->tree().leafCount())
            file_.corrupt("grid " + quoted(display_name(e)) + ": its topology and its layout disagree on the number of leaves");
        return out;
    }


    /// Metadata and class of a grid, without its voxels.
    vdb::GridBase::Ptr read_grid_metadata(size_t index) {
        const Entry& e = entries_.at(index);
        if (e.grid) return e.grid;
        e.gd.seekToGrid(file_.is);
        check_.check_grid_header();
        vdb::GridBase::Ptr grid = vdb::GridBase::createGrid(e.gd.gridType());
        readGridCompression(file_.is);
        grid->readMeta(file_.is);
        return grid;
    }

    /// Whether read_grid checks this grid's layout before handing it to OpenVDB (see check_layout).
    bool can_check_layout(const Entry& e) const { return LayoutCheck::layout_of(e.gd) != nullptr; }

private:
    /// Archive::readHeader, except for format 225: OpenVDB 11 and 12 (Blender 5's) write it, and it only announces
    /// their half-float grid type, which this build refuses by its type name as any unregistered type; every
    /// other grid is stored as in 224. readHeader would print "unsupported VDB file format" on the user's console
    /// for each such file although it reads, so its header is read as 224's, from a copy that says so.
    void read_header() {
        constexpr uint32_t kHalfGridFormat = 225;
        constexpr std::streamsize kHeaderBytes = 8 + 4 + 8 + 1 + 36;  // magic, format, library, offsets flag, UUID
        uint32_t format = 0;
        if (file_.size >= kHeaderBytes) {
            file_.is.seekg(8);
            file_.is.read(reinterpret_cast<char*>(&format), sizeof format);
            file_.is.seekg(0);
        }
        if (format != kHalfGridFormat || vdb::OPENVDB_FILE_VERSION >= kHalfGridFormat) {
            readHeader(file_.is);
            return;
        }
        std::string header(size_t(kHeaderBytes), '\0');
        file_.is.read(header.data(), kHeaderBytes);
        const uint32_t readable = vdb::OPENVDB_FILE_VERSION;
        std::memcpy(header.data() + 8, &readable, sizeof readable);
        std::istringstream copy(header);
        readHeader(copy);  // the file's stream is past the header already
    }

    /// The grid whose tree an instance shares. `depth` stops a corrupt file's cycle of instances.
    vdb::GridBase::Ptr instance_parent(const Entry& e, size_t depth = 0) {
        for (size_t i = 0; i < entries_.size(); ++i)
            if (entries_[i].gd.uniqueName() == e.gd.instanceParentName() && depth < entries_.size())
                return read_grid(i, depth + 1);
        file_.corrupt("grid " + quoted(display_name(e)) + " is an instance of a grid that is not in the file");
    }

    /// The layout check's end of a grid (-1: not checked) must be its descriptor's.
    void check_grid_end(const Entry& e, int64_t end) const {
        if (end >= 0 && e.gd.getEndPos() > 0 && end != e.gd.getEndPos())
            file_.corrupt("grid " + quoted(display_name(e)) + " should end at byte " + std::to_string(e.gd.getEndPos()) +
                          " but its nodes end at byte " + std::to_string(end));
    }

    /// Read a whole grid starting at the stream position (just after its descriptor), once its
    /// layout has been checked. Leaves the stream at the end of the grid.
    vdb::GridBase::Ptr read_at_current(const Entry& e) {
        const int64_t start = file_.tell();
        check_.check_grid_header();
        check_.check_affine_map(display_name(e));
        const int64_t end = check_layout(e);
        const std::string name = quoted(display_name(e));
        check_grid_end(e, end);
        file_.is.seekg(start);
        vdb::GridBase::Ptr grid = vdb::GridBase::createGrid(e.gd.gridType());
        grid->setSaveFloatAsHalf(e.gd.saveFloatAsHalf());
        readGrid(grid, e.gd, file_.is);
        // The stream must end up exactly where the layout check (or the descriptor) says it ends.
        const int64_t expected = end >= 0 ? end : e.gd.getEndPos();
        if (expected > 0 && file_.tell() != expected)
            file_.corrupt("grid " + name + " should end at byte " + std::to_string(expected) +
                          " but its data ends at byte " + std::to_string(file_.tell()));
        return grid;
    }

    /// Walk the grid at the stream position (just after its descriptor) with the layout check; returns
    /// where it ends, or -1 when its layout is unknown. Leaves the stream where it was.
    int64_t check_layout(const Entry& e, std::vector<int64_t>* leaf_positions = nullptr) {
        if (!LayoutCheck::layout_of(e.gd) || fileVersion() < vdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) return -1;
        const int64_t start = file_.tell();
        readGridCompression(file_.is);
        const int64_t end = check_.walk(e.gd, vdb::io::getDataCompression(file_.is), leaf_positions);
        file_.is.seekg(start);
        return end;
    }

    SizedStream file_;
    LayoutCheck check_{file_};
    std::vector<Entry> entries_;
};

inline std::string grid_list(const Reader& r) {
    std::string s;
    for (const Entry& e : r.entries()) {
        if (!s.empty()) s += ", ";
        s += Reader::display_name(e) + " (" + e.value_type + ")";
    }
    return s.empty() ? "none" : s;
}

/// Index of the grid to read: the one asked for, else 'density', else the first float grid,
/// else the first other scalar grid.
inline size_t choose_grid(const Reader& r, const std::string& requested) {
    const auto& entries = r.entries();
    if (!requested.empty()) {
        const int i = r.find(requested);
        if (i < 0)
            throw GridError(quoted(r.path()) + " has no grid named " + quoted(requested) +
                            "; grids in the file: " + grid_list(r));
        return size_t(i);
    }
    if (entries.empty()) throw GridError(quoted(r.path()) + " contains no grids");
    const int density = r.find("density");
    if (density >= 0) return size_t(density);
    for (size_t i = 0; i < entries.size(); ++i)
        if (entries[i].value_type == "float" || entries[i].value_type == "double") return i;
    for (size_t i = 0; i < entries.size(); ++i)
        if (entries[i].scalar) return i;
    throw GridError(quoted(r.path()) + " has no scalar grid to render; grids in the file: " + grid_list(r));
}

/// Run `f`, turning anything that escapes OpenVDB or the C++ library into VdbReadError naming the file.
/// pcvr errors (FileNotFound, GridError, ...) pass through unchanged.
template <typename F>
auto guard_read(const std::string& path, F&& f) -> decltype(f()) {
    const std::string prefix = "cannot read " + quoted(path) + ": ";
    try {
        return f();
    } catch (const FileNotFound& e) {
        throw FileNotFound(valid_utf8(e.what()));
    } catch (const GridError& e) {
        throw GridError(valid_utf8(e.what()));
    } catch (const VdbReadError& e) {
        throw VdbReadError(valid_utf8(e.what()));
    } catch (const Error&) {
        throw;
    } catch (const std::ios_base::failure&) {
        throw VdbReadError(prefix + "unexpected end of file or read error (the file is truncated or corrupt)");
    } catch (const std::bad_alloc&) {
        throw VdbReadError(prefix + "out of memory (the file may be corrupt)");
    } catch (const vdb::Exception& e) {
        throw VdbReadError(valid_utf8(prefix + e.what()));
    } catch (const std::exception& e) {
        throw VdbReadError(valid_utf8(prefix + e.what() + " (the file may be corrupt)"));
    } catch (...) {
        throw VdbReadError(prefix + "unknown error");
    }
}

}  // namespace pcvr::vdb_reader
