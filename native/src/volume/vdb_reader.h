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
///   - a grid's nodes are walked, checking every chunk size, before OpenVDB reads them ("Layout check").
/// Nothing is delay-loaded: a grid that reads without error is complete in memory, so a bad file fails
/// here, never later inside the renderer. Every failure becomes a pcvr exception naming the file.
///
#pragma once

#include <openvdb/io/Archive.h>
#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/openvdb.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <new>
#include <string>
#include <vector>

#include "pcvr/errors.h"

namespace pcvr::vdb_reader {

namespace vdb = openvdb;
using vdb::io::GridDescriptor;

inline std::string quoted(const std::string& s) { return "'" + s + "'"; }

/// `s` with every byte that is not part of valid UTF-8 replaced by U+FFFD. Names and messages read
/// from a file go to Python as str, which a corrupt or Latin-1 name would otherwise break.
inline std::string valid_utf8(const std::string& s) {
    std::string out;
    out.reserve(s.size());
    const auto* p = reinterpret_cast<const unsigned char*>(s.data());
    const size_t n = s.size();
    for (size_t i = 0; i < n;) {
        const unsigned char c = p[i];
        size_t len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
        bool ok = len > 0 && i + len <= n && !(len == 2 && c < 0xC2) && !(len == 4 && c > 0xF4);
        for (size_t k = 1; ok && k < len; ++k) ok = (p[i + k] & 0xC0) == 0x80;
        if (ok && len == 3) {  // no overlong forms, no UTF-16 surrogates
            ok = !(c == 0xE0 && p[i + 1] < 0xA0) && !(c == 0xED && p[i + 1] >= 0xA0);
        } else if (ok && len == 4) {
            ok = !(c == 0xF0 && p[i + 1] < 0x90) && !(c == 0xF4 && p[i + 1] >= 0x90);
        }
        if (ok) {
            out.append(s, i, len);
            i += len;
        } else {
            out += "\xEF\xBF\xBD";
            ++i;
        }
    }
    return out;
}

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
    explicit Reader(const std::string& path) : path_(path) {
        namespace fs = std::filesystem;
        std::error_code ec;
        const fs::file_status status = fs::status(path, ec);
        if (status.type() == fs::file_type::not_found) throw FileNotFound("VDB file not found: " + quoted(path));
        if (ec) throw VdbReadError("cannot read " + quoted(path) + ": " + ec.message());
        if (fs::is_directory(status)) throw VdbReadError("cannot read " + quoted(path) + ": is a directory");
        // Devices and pipes have no size to check against (and a FIFO would block).
        if (!fs::is_regular_file(status)) throw VdbReadError("cannot read " + quoted(path) + ": not a regular file");

        is_.open(path, std::ios::in | std::ios::binary);
        if (!is_) throw VdbReadError("cannot open " + quoted(path) + ": " + std::strerror(errno));
        is_.seekg(0, std::ios::end);
        size_ = int64_t(is_.tellg());
        is_.seekg(0);
        // From here on a short read throws std::ios_base::failure instead of yielding garbage.
        is_.exceptions(std::ios::failbit | std::ios::badbit);

        if (size_ < 8) throw_corrupt("too short to be a VDB file (" + std::to_string(size_) + " bytes)");
        readHeader(is_);  // throws "not a VDB file" on a wrong magic number
        // Tag the stream with the header's versions and compression, as io::File::open does.
        stream_meta_ = std::make_shared<vdb::io::StreamMetadata>();
        stream_meta_->setSeekable(true);
        vdb::io::setStreamMetadataPtr(is_, stream_meta_, /*transfer=*/false);
        setFormatVersion(is_);
        setLibraryVersion(is_);
        setDataCompression(is_);

        check_metamap("file metadata");
        vdb::MetaMap().readMeta(is_);

        const int32_t count = readGridCount(is_);
        // A descriptor takes at least 3 string lengths and 3 offsets.
        if (count < 0 || int64_t(count) * 36 > remaining()) throw_corrupt("invalid grid count " + std::to_string(count));
        entries_.reserve(size_t(count));
        for (int32_t i = 0; i < count; ++i) {
            Entry e;
            if (fileVersion() >= vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING)
                check_strings(3, "grid descriptor");
            else
                check_strings(2, "grid descriptor");
            const vdb::GridBase::Ptr empty = e.gd.read(is_);  // throws on unregistered grid types
            e.value_type = empty->valueType();
            e.scalar = is_scalar(*empty);
            if (inputHasGridOffsets()) {
                const int64_t here = tell();
                if (e.gd.getGridPos() < here || e.gd.getEndPos() < e.gd.getGridPos())
                    throw_corrupt("invalid offsets for grid " + quoted(display_name(e)));
                if (e.gd.getEndPos() > size_)
                    throw_corrupt("truncated: grid " + quoted(display_name(e)) + " ends at byte " +
                                  std::to_string(e.gd.getEndPos()) + " but the file has " +
                                  std::to_string(size_) + " bytes");
                e.gd.seekToEnd(is_);
            } else {
                // Written as a stream (io::Stream): no offsets, so grids can only be read in order;
                // an instance's parent comes before it.
                e.grid = read_at_current(e);
                if (e.gd.isInstance()) e.grid->setTree(instance_parent(e)->baseTreePtr());
            }
            entries_.push_back(std::move(e));
        }
    }

    const std::string& path() const { return path_; }
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
        e.gd.seekToGrid(is_);
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
        const std::string context = "grid " + quoted(display_name(e)) + " in " + vdb_reader::quoted(path_);
        if (e.grid || e.gd.isInstance() || e.gd.gridType() != vdb::FloatTree::treeType() ||
            fileVersion() < vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING)
            throw GridError(context + " cannot be read a part at a time (only float grids with a tree of their own, "
                                      "from OpenVDB 3 or later, can): read it whole");
        e.gd.seekToGrid(is_);
        const int64_t start = tell();
        check_grid_header();
        check_affine_map(e);
        Topology out;
        leaf_positions_ = &out.leaf_positions;
        const int64_t end = check_layout(e);
        leaf_positions_ = nullptr;
        check_grid_end(e, end);
        is_.seekg(start);
        readGridCompression(is_);
        out.grid = vdb::FloatGrid::create();
        out.grid->setSaveFloatAsHalf(e.gd.saveFloatAsHalf());
        out.grid->readMeta(is_);
        if (out.grid->getGridClass() == vdb::GRID_LEVEL_SET)
            throw GridError(context + " is a level set, which is converted to a fog volume as a whole: read it whole");
        vdb::io::setGridClass(is_, out.grid->getGridClass());
        out.grid->readTransform(is_);
        out.grid->readTopology(is_);
        // Leaves whose inactive values were left out of the file take the background.
        vdb::io::setGridBackgroundValuePtr(is_, &out.grid->tree().background());
        if (out.leaf_positions.size() != out.grid->tree().leafCount())
            throw_corrupt("grid " + quoted(display_name(e)) + ": its topology and its layout disagree on the number of leaves");
        return out;
    }

    /// Fill the values of `leaves` (consecutive in the tree's leaf order, their value masks set by
    /// read_topology) from their records at `positions`, on all threads: a run of leaves a task, each
    /// through a stream of its own tagged as the Reader's, with its own copy of the stream metadata
    /// (OpenVDB counts the leaves it reads in it). The Reader's own stream is not moved.
    template <typename Leaf>
    void read_leaves_parallel(const std::vector<Leaf*>& leaves, const int64_t* positions, bool half) const {
        constexpr size_t kLeavesPerTask = 64;  // 128 KiB of values: a file open is noise beside it
        tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), kLeavesPerTask),
                          [&](const tbb::blocked_range<size_t>& run) {
            std::ifstream in(path_, std::ios::in | std::ios::binary);
            if (!in) throw VdbReadError("cannot open " + vdb_reader::quoted(path_) + ": " + std::strerror(errno));
            in.copyfmt(is_);  // versions, compression, background, and throwing on a short read
            auto meta = std::make_shared<vdb::io::StreamMetadata>(*stream_meta_);
            vdb::io::setStreamMetadataPtr(in, meta, /*transfer=*/false);
            in.seekg(positions[run.begin()]);
            for (size_t i = run.begin(); i != run.end(); ++i) leaves[i]->readBuffers(in, half);
        });
    }

    /// Metadata and class of a grid, without its voxels.
    vdb::GridBase::Ptr read_grid_metadata(size_t index) {
        const Entry& e = entries_.at(index);
        if (e.grid) return e.grid;
        e.gd.seekToGrid(is_);
        check_grid_header();
        vdb::GridBase::Ptr grid = vdb::GridBase::createGrid(e.gd.gridType());
        readGridCompression(is_);
        grid->readMeta(is_);
        return grid;
    }

    /// Whether read_grid checks this grid's layout before handing it to OpenVDB (see check_layout).
    bool can_check_layout(const Entry& e) const { return layout_of(e) != nullptr; }

private:
    [[noreturn]] void throw_corrupt(const std::string& what) const {
        throw VdbReadError("cannot read " + quoted(path_) + ": " + what);
    }

    /// The grid whose tree an instance shares. `depth` stops a corrupt file's cycle of instances.
    vdb::GridBase::Ptr instance_parent(const Entry& e, size_t depth = 0) {
        for (size_t i = 0; i < entries_.size(); ++i)
            if (entries_[i].gd.uniqueName() == e.gd.instanceParentName() && depth < entries_.size())
                return read_grid(i, depth + 1);
        throw_corrupt("grid " + quoted(display_name(e)) + " is an instance of a grid that is not in the file");
    }

    int64_t tell() { return int64_t(is_.tellg()); }
    int64_t remaining() { return size_ - tell(); }

    uint32_t read_u32() {
        uint32_t v = 0;
        is_.read(reinterpret_cast<char*>(&v), sizeof(v));
        return v;
    }

    /// Read a length-prefixed string, refusing lengths beyond the end of the file.
    std::string read_string(const char* what) {
        const uint32_t n = read_u32();
        if (int64_t(n) > remaining()) throw_corrupt(std::string("corrupt ") + what + " (string length " + std::to_string(n) + ")");
        std::string s(n, '\0');
        if (n) is_.read(&s[0], n);
        return s;
    }

    /// Check the next `n` length-prefixed strings fit in the file; leaves the stream where it was.
    void check_strings(int n, const char* what) {
        const int64_t start = tell();
        for (int i = 0; i < n; ++i) {
            const uint32_t len = read_u32();
            if (int64_t(len) > remaining()) throw_corrupt(std::string("corrupt ") + what + " (string length " + std::to_string(len) + ")");
            is_.seekg(len, std::ios::cur);
        }
        is_.seekg(start);
    }

    /// Walk a MetaMap's size fields, so MetaMap::readMeta never allocates from a corrupt one.
    /// Leaves the stream where it was; returns where the MetaMap ends.
    int64_t check_metamap(const char* what) {
        const int64_t start = tell();
        const uint32_t count = read_u32();
        if (int64_t(count) * 12 > remaining()) throw_corrupt(std::string("corrupt ") + what + " (count " + std::to_string(count) + ")");
        for (uint32_t i = 0; i < count; ++i) {
            read_string(what);
            const std::string type = read_string(what);
            const uint32_t bytes = read_u32();
            if (int64_t(bytes) > remaining()) throw_corrupt(std::string("corrupt ") + what + " (size " + std::to_string(bytes) + ")");
            if (vdb::Metadata::isRegisteredType(type)) {
                // Fixed-size types read sizeof(T) whatever the size field says: they must agree, or
                // OpenVDB and this walk would part ways.
                const vdb::Index32 fixed = vdb::Metadata::createMetadata(type)->size();
                if (fixed != 0 && fixed != bytes) throw_corrupt(std::string("corrupt ") + what + " (" + type + " of size " + std::to_string(bytes) + ")");
                if (type == vdb::io::DelayedLoadMetadata::staticTypeName() && bytes > 0)
                    check_delayed_load_table(tell() + bytes, what);
            }
            is_.seekg(bytes, std::ios::cur);
        }
        const int64_t end = tell();
        is_.seekg(start);
        return end;
    }

    /// DelayedLoadMetadata (ending at `end`) holds a per-leaf mask and a per-leaf size table, each
    /// stored raw or as one blosc chunk: [leaf count][bytes][mask][bytes][sizes], bytes 0 for raw
    /// data, and 0xFFFFFFFF for no sizes. OpenVDB resizes the tables to the count blindly and hands
    /// blosc the chunk's own header, which blosc trusts (fuzzing found a corrupt one that made it
    /// read past a 56-byte buffer): the count, both sizes and each chunk's header must agree.
    /// Leaves the stream where it was.
    void check_delayed_load_table(int64_t end, const char* what) {
        const int64_t start = tell();
        const std::string corrupt = std::string("corrupt ") + what + " (delayed-load table)";
        if (end - start < 8) throw_corrupt(corrupt);
        const uint32_t leaves = read_u32();
        if (int64_t(leaves) > size_) throw_corrupt(corrupt);  // each leaf takes far more than a byte of the file
        auto table = [&](int64_t bytes_per_leaf, bool optional) {
            if (end - tell() < 4) throw_corrupt(corrupt);
            const uint32_t stored = read_u32();
            if (optional && stored == std::numeric_limits<uint32_t>::max()) return;
            const int64_t raw = int64_t(leaves) * bytes_per_leaf;
            if ((stored == 0 ? raw : int64_t(stored)) > end - tell()) throw_corrupt(corrupt);
            if (stored == 0) {
                is_.seekg(raw, std::ios::cur);
                return;
            }
            std::array<uint8_t, 16> header{};  // blosc: uncompressed size at byte 4, chunk size at 12
            if (stored < header.size()) throw_corrupt(corrupt);
            is_.read(reinterpret_cast<char*>(header.data()), std::streamsize(header.size()));
            auto u32 = [&header](int at) {
                return uint32_t(header[at]) | uint32_t(header[at + 1]) << 8 | uint32_t(header[at + 2]) << 16 | uint32_t(header[at + 3]) << 24;
            };
            // OpenVDB pads tables under 128 bytes to 128 before compressing them.
            const int64_t uncompressed = u32(4);
            if (!(uncompressed == raw || (raw < 128 && uncompressed == 128)) || u32(12) != stored) throw_corrupt(corrupt);
            is_.seekg(int64_t(stored) - int64_t(header.size()), std::ios::cur);
        };
        table(sizeof(vdb::io::DelayedLoadMetadata::MaskType), false);
        table(sizeof(vdb::io::DelayedLoadMetadata::CompressedSizeType), true);
        is_.seekg(start);
    }

    /// Where the transform (its map's type name) of the grid at the stream position starts; -1 in
    /// old files, which store it after the tree. Leaves the stream where it was.
    int64_t transform_position() {
        const int64_t start = tell();
        if (fileVersion() >= vdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) read_u32();
        const int64_t meta_end = check_metamap("grid metadata");
        is_.seekg(start);
        return fileVersion() >= vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING ? meta_end : -1;
    }

    /// Check what precedes a grid's tree (compression flags, metadata, transform type) at the stream
    /// position; leaves the stream where it was.
    void check_grid_header() {
        const int64_t start = tell();
        const int64_t transform = transform_position();
        if (transform >= 0) {
            is_.seekg(transform);
            check_strings(1, "grid transform");
        }
        is_.seekg(start);
    }

    /// OpenVDB refuses an affine map with a determinant below 3e-15 (voxels under about 1.4e-5 units)
    /// with a bare "nearly singular matrix"; say what it means instead. (Grids written by pcvr_native
    /// never hold one: they keep such scales in metadata, see grid_data.h.) Leaves the stream where it was.
    void check_affine_map(const Entry& e) {
        const int64_t start = tell();
        const int64_t transform = transform_position();
        if (transform >= 0) {
            is_.seekg(transform);
            if (read_string("grid transform") == vdb::math::AffineMap::mapType() && remaining() >= 16 * 8) {
                vdb::Mat4d a;
                a.read(is_);
                const double det = std::abs(a.getMat3().det()), limit = 3.0 * vdb::math::Tolerance<double>::value();
                if (det < limit) {
                    std::ostringstream msg;
                    msg << "grid " << quoted(display_name(e)) << " in " << quoted(path_) << " has voxels of about "
                        << std::cbrt(det) << " world units (transform determinant " << det
                        << "), smaller than OpenVDB can load (determinant at least " << limit
                        << ", voxels of about 1.4e-05 units): store it in a finer unit (e.g. micrometres "
                           "instead of metres) and scale the object instead, or write it with "
                           "pcvr_native.Grid.write_vdb, which keeps such scales in metadata";
                    throw GridError(msg.str());
                }
            }
        }
        is_.seekg(start);
    }

    /// The layout check's end of a grid (-1: not checked) must be its descriptor's.
    void check_grid_end(const Entry& e, int64_t end) const {
        if (end >= 0 && e.gd.getEndPos() > 0 && end != e.gd.getEndPos())
            throw_corrupt("grid " + quoted(display_name(e)) + " should end at byte " + std::to_string(e.gd.getEndPos()) +
                          " but its nodes end at byte " + std::to_string(end));
    }

    /// Read a whole grid starting at the stream position (just after its descriptor), once its
    /// layout has been checked. Leaves the stream at the end of the grid.
    vdb::GridBase::Ptr read_at_current(const Entry& e) {
        const int64_t start = tell();
        check_grid_header();
        check_affine_map(e);
        const int64_t end = check_layout(e);
        const std::string name = quoted(display_name(e));
        check_grid_end(e, end);
        is_.seekg(start);
        vdb::GridBase::Ptr grid = vdb::GridBase::createGrid(e.gd.gridType());
        grid->setSaveFloatAsHalf(e.gd.saveFloatAsHalf());
        readGrid(grid, e.gd, is_);
        // The stream must end up exactly where the layout check (or the descriptor) says it ends.
        const int64_t expected = end >= 0 ? end : e.gd.getEndPos();
        if (expected > 0 && tell() != expected)
            throw_corrupt("grid " + name + " should end at byte " + std::to_string(expected) +
                          " but its data ends at byte " + std::to_string(tell()));
        return grid;
    }

    // ---- Layout check -------------------------------------------------------------------------
    // OpenVDB trusts the chunk sizes in a file: for an uncompressed chunk inside a zip or blosc file
    // it reads the stored size's worth of bytes into a buffer sized for the node, before comparing
    // the two, so one corrupt size field overflows the heap. So before OpenVDB reads a grid, this walks
    // the grid's nodes the way OpenVDB's readTopology / readBuffers will (file format >= 222, the
    // standard 5-4-3 trees) and checks every size field against the node it belongs to and the
    // bytes left in the file, without decompressing anything. Older files are read unchecked.

    /// How a tree's values are stored: bytes per value (and per value saved as half), leaf flavour.
    struct ValueLayout {
        const char* grid_type;  ///< as in the file; only the standard 5-4-3 trees
        int bytes;
        int half_bytes;  ///< bytes per value when the grid is saved as half floats
        enum Leaf { kValues, kBool, kMask } leaf;
    };

    static const ValueLayout* layout_of(const Entry& e) {
        static const ValueLayout kLayouts[] = {
            {"Tree_float_5_4_3", 4, 2, ValueLayout::kValues}, {"Tree_double_5_4_3", 8, 2, ValueLayout::kValues},
            {"Tree_int32_5_4_3", 4, 4, ValueLayout::kValues}, {"Tree_int64_5_4_3", 8, 8, ValueLayout::kValues},
            {"Tree_vec3s_5_4_3", 12, 6, ValueLayout::kValues}, {"Tree_vec3d_5_4_3", 24, 6, ValueLayout::kValues},
            {"Tree_vec3i_5_4_3", 12, 12, ValueLayout::kValues}, {"Tree_bool_5_4_3", 1, 1, ValueLayout::kBool},
            {"Tree_mask_5_4_3", 1, 1, ValueLayout::kMask},
        };
        for (const ValueLayout& l : kLayouts)
            if (e.gd.gridType() == l.grid_type) return &l;
        return nullptr;
    }

    struct LayoutState {
        const ValueLayout* layout;
        uint32_t compression;
        bool half;  ///< values stored as half floats
        /// Active-voxel count of every leaf, grouped by root child in the order readBuffers visits
        /// them: the root's std::map order (a later child with the same origin replaces the earlier).
        std::map<std::array<int32_t, 3>, std::vector<uint16_t>> leaves;
    };

    /// Walk the grid at the stream position; returns where it ends, or -1 when its layout is unknown.
    /// Leaves the stream where it was.
    int64_t check_layout(const Entry& e) {
        const ValueLayout* layout = layout_of(e);
        if (!layout || fileVersion() < vdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) return -1;
        const int64_t start = tell();
        readGridCompression(is_);
        LayoutState st{layout, vdb::io::getDataCompression(is_), e.gd.saveFloatAsHalf() && layout->half_bytes != layout->bytes, {}};
        {
            // Metadata and transform are already checked: let OpenVDB step over them.
            vdb::GridBase::Ptr scratch = vdb::GridBase::createGrid(e.gd.gridType());
            scratch->readMeta(is_);
            scratch->readTransform(is_);
        }
        walk_pos_ = tell();
        if (!e.gd.isInstance()) {
            check_topology(st);
            check_buffers(st);
        }
        const int64_t end = walk_pos_;
        is_.seekg(start);
        return end;
    }

    // The walk keeps its own position and steps over data with ignore(): tellg and seekg cost a
    // system call each and discard the stream's buffer.
    int64_t walk_pos_ = 0;
    std::vector<int64_t>* leaf_positions_ = nullptr;  ///< where check_buffers records each leaf, when set

    void walk_read(void* dst, int64_t n, const char* what) {
        if (n > size_ - walk_pos_) throw_corrupt(std::string("truncated ") + what);
        is_.read(static_cast<char*>(dst), std::streamsize(n));
        walk_pos_ += n;
    }

    void skip(int64_t n, const char* what) {
        if (n < 0 || n > size_ - walk_pos_) throw_corrupt(std::string("corrupt ") + what + " (size " + std::to_string(n) + ")");
        is_.ignore(std::streamsize(n));
        walk_pos_ += n;
    }

    template <typename T>
    T read_pod(const char* what) {
        T v{};
        walk_read(&v, sizeof(T), what);
        return v;
    }

    /// Read a node mask of `bits` bits; returns its words.
    std::vector<uint64_t> read_mask(size_t bits) {
        std::vector<uint64_t> words(bits / 64);
        walk_read(words.data(), int64_t(bits / 8), "node mask");
        return words;
    }

    static uint32_t count_on(const std::vector<uint64_t>& mask) {
        uint32_t n = 0;
        for (uint64_t w : mask) n += uint32_t(__builtin_popcountll(w));
        return n;
    }

    /// Mirrors Tree::readTopology -> RootNode / InternalNode / LeafNode::readTopology.
    void check_topology(LayoutState& st) {
        const int bytes = st.layout->bytes;
        read_pod<int32_t>("tree");  // buffer count
        skip(bytes, "root node");  // background
        const uint32_t tiles = read_pod<uint32_t>("root node");
        const uint32_t children = read_pod<uint32_t>("root node");
        skip(int64_t(tiles) * (12 + bytes + 1), "root tiles");  // origin, value, active flag
        // A child takes at least its origin and two 32^3-bit masks.
        if (int64_t(children) * (12 + 2 * 4096) > size_ - walk_pos_) throw_corrupt("corrupt root node (child count)");
        for (uint32_t n = 0; n < children; ++n) {
            const auto origin = read_pod<std::array<int32_t, 3>>("root node");
            std::vector<uint16_t>& leaves = st.leaves[origin];
            leaves.clear();
            check_internal_topology(st, 5, leaves);
        }
    }

    void check_internal_topology(LayoutState& st, int log2dim, std::vector<uint16_t>& leaves) {
        const size_t n = size_t(1) << (3 * log2dim);
        const std::vector<uint64_t> child_mask = read_mask(n);
        const std::vector<uint64_t> value_mask = read_mask(n);
        check_compressed_values(st, uint32_t(n), count_on(value_mask));
        for (size_t w = 0; w < child_mask.size(); ++w)
            for (uint64_t bits = child_mask[w]; bits; bits &= bits - 1) {
                if (log2dim == 5) {
                    check_internal_topology(st, 4, leaves);
                } else {
                    // Value leaves and bool leaves store their value mask here, mask leaves their
                    // only mask; either way 512 bits.
                    leaves.push_back(uint16_t(count_on(read_mask(512))));
                }
            }
    }

    /// Mirrors LeafNode::readBuffers for every leaf, in RootNode::readBuffers' order.
    void check_buffers(LayoutState& st) {
        for (const auto& [origin, leaves] : st.leaves)
            for (uint16_t active : leaves) {
                switch (st.layout->leaf) {
                    case ValueLayout::kValues:
                        if (leaf_positions_) leaf_positions_->push_back(walk_pos_);
                        skip(64, "leaf");  // value mask, skipped on seekable streams
                        check_compressed_values(st, 512, active);
                        break;
                    case ValueLayout::kBool: skip(64 + 12 + 64, "leaf"); break;  // value mask, origin, values
                    case ValueLayout::kMask: skip(64 + 12, "leaf"); break;       // mask, origin
                }
            }
    }

    /// Mirrors io::readCompressedValues (format >= 222) and io::readData.
    void check_compressed_values(const LayoutState& st, uint32_t count, uint32_t active) {
        enum { kOneInactive = 2, kMaskNoInactive = 3, kMaskOneInactive = 4, kMaskTwoInactive = 5, kAllValues = 6 };
        const int8_t flags = read_pod<int8_t>("node values");
        if (flags == kOneInactive || flags == kMaskOneInactive || flags == kMaskTwoInactive)
            skip(st.layout->bytes * (flags == kMaskTwoInactive ? 2 : 1), "inactive values");
        if (flags == kMaskNoInactive || flags == kMaskOneInactive || flags == kMaskTwoInactive)
            skip(count / 8, "selection mask");
        const bool mask_compressed = st.compression & vdb::io::COMPRESS_ACTIVE_MASK;
        const uint32_t stored = (mask_compressed && flags != kAllValues) ? active : count;
        if (st.half && stored == 0) return;  // HalfReader reads nothing for an empty buffer
        const int64_t bytes = int64_t(stored) * (st.half ? st.layout->half_bytes : st.layout->bytes);
        if (!(st.compression & (vdb::io::COMPRESS_BLOSC | vdb::io::COMPRESS_ZIP))) {
            skip(bytes, "values");
            return;
        }
        // Compressed chunk: int64 size, negative for a chunk stored uncompressed.
        const int64_t size = read_pod<int64_t>("node values");
        if (size <= 0) {
            if (size == std::numeric_limits<int64_t>::min() || -size != bytes)
                throw_corrupt("corrupt chunk size " + std::to_string(size) + " for " + std::to_string(bytes) + " bytes of values");
            skip(-size, "values");
            return;
        }
        if (st.compression & vdb::io::COMPRESS_BLOSC) {
            // blosc_decompress trusts the sizes in the chunk's own 16-byte header: they must match.
            const auto header = read_pod<std::array<uint8_t, 16>>("blosc chunk");
            auto u32 = [&header](int at) {
                return uint32_t(header[at]) | uint32_t(header[at + 1]) << 8 | uint32_t(header[at + 2]) << 16 | uint32_t(header[at + 3]) << 24;
            };
            if (size < 16 || int64_t(u32(4)) != bytes || int64_t(u32(12)) != size)
                throw_corrupt("corrupt blosc chunk header");
            skip(size - 16, "compressed values");
        } else {
            skip(size, "compressed values");
        }
    }

    std::string path_;
    std::ifstream is_;
    int64_t size_ = 0;
    vdb::io::StreamMetadata::Ptr stream_meta_;
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
