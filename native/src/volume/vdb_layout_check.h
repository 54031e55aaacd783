/// @file vdb_layout_check.h
/// @brief Validation of a VDB file's layout before OpenVDB reads it: metadata sizes, transforms and every
/// node's chunk sizes, checked against the node they belong to and the bytes left in the file.
///
/// OpenVDB trusts the chunk sizes in a file: for an uncompressed chunk inside a zip or blosc file it
/// reads the stored size's worth of bytes into a buffer sized for the node, before comparing the two,
/// so one corrupt size field overflows the heap. So before OpenVDB reads a grid, walk() goes over the
/// grid's nodes the way OpenVDB's readTopology / readBuffers will (file format >= 222, the standard
/// 5-4-3 trees) and checks every size field against the node it belongs to and the bytes left in the
/// file, without decompressing anything. Older files are read unchecked.
///
/// Private to the VDB reader (vdb_reader.h), which calls it before every read OpenVDB makes.
#pragma once

#include <openvdb/io/GridDescriptor.h>
#include <openvdb/openvdb.h>

#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pcvr/errors.h"
#include "volume/vdb_delayed_load.h"
#include "volume/vdb_stream.h"

namespace pcvr::vdb_reader {

using vdb::io::GridDescriptor;

/// The checks of one file's stream. Every check but walk() leaves the stream where it was.
class LayoutCheck {
public:
    explicit LayoutCheck(SizedStream& file) : file_(file) {}

    uint32_t version = 0;  ///< the file's format version, once its header is read

    /// Walk a MetaMap's size fields, so MetaMap::readMeta never allocates from a corrupt one.
    /// Leaves the stream where it was; returns where the MetaMap ends.
    int64_t check_metamap(const char* what) {
        const int64_t start = file_.tell();
        const uint32_t count = file_.read_u32();
        if (int64_t(count) * 12 > file_.remaining()) file_.corrupt(std::string("corrupt ") + what + " (count " + std::to_string(count) + ")");
        for (uint32_t i = 0; i < count; ++i) {
            file_.read_string(what);
            const std::string type = file_.read_string(what);
            const uint32_t bytes = file_.read_u32();
            if (int64_t(bytes) > file_.remaining()) file_.corrupt(std::string("corrupt ") + what + " (size " + std::to_string(bytes) + ")");
            if (vdb::Metadata::isRegisteredType(type)) {
                // Fixed-size types read sizeof(T) whatever the size field says: they must agree, or
                // OpenVDB and this walk would part ways.
                const vdb::Index32 fixed = vdb::Metadata::createMetadata(type)->size();
                if (fixed != 0 && fixed != bytes) file_.corrupt(std::string("corrupt ") + what + " (" + type + " of size " + std::to_string(bytes) + ")");
                if (type == vdb::io::DelayedLoadMetadata::staticTypeName() && bytes > 0)
                    check_delayed_load_table(file_, file_.tell() + bytes, what);
            }
            file_.is.seekg(bytes, std::ios::cur);
        }
        const int64_t end = file_.tell();
        file_.is.seekg(start);
        return end;
    }

    /// Where the transform (its map's type name) of the grid at the stream position starts; -1 in
    /// old files, which store it after the tree. Leaves the stream where it was.
    int64_t transform_position() {
        const int64_t start = file_.tell();
        if (version >= vdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) file_.read_u32();
        const int64_t meta_end = check_metamap("grid metadata");
        file_.is.seekg(start);
        return version >= vdb::OPENVDB_FILE_VERSION_GRID_INSTANCING ? meta_end : -1;
    }

    /// Check what precedes a grid's tree (compression flags, metadata, transform type) at the stream
    /// position; leaves the stream where it was.
    void check_grid_header() {
        const int64_t start = file_.tell();
        const int64_t transform = transform_position();
        if (transform >= 0) {
            file_.is.seekg(transform);
            file_.check_strings(1, "grid transform");
        }
        file_.is.seekg(start);
    }

    /// OpenVDB refuses an affine map with a determinant below 3e-15 (voxels under about 1.4e-5 units)
    /// with a bare "nearly singular matrix"; say what it means instead. (Grids written by pcvr_native
    /// never hold one: they keep such scales in metadata, see grid_data.h.) Leaves the stream where it was.
    void check_affine_map(const std::string& grid_name) {
        const int64_t start = file_.tell();
        const int64_t transform = transform_position();
        if (transform >= 0) {
            file_.is.seekg(transform);
            if (file_.read_string("grid transform") == vdb::math::AffineMap::mapType() && file_.remaining() >= 16 * 8) {
                vdb::Mat4d a;
                a.read(file_.is);
                const double det = std::abs(a.getMat3().det()), limit = 3.0 * vdb::math::Tolerance<double>::value();
                if (det < limit) {
                    std::ostringstream msg;
                    msg << "grid " << quoted(grid_name) << " in " << vdb_reader::quoted(file_.path) << " has voxels of about "
                        << std::cbrt(det) << " world units (transform determinant " << det
                        << "), smaller than OpenVDB can load (determinant at least " << limit
                        << ", voxels of about 1.4e-05 units): store it in a finer unit (e.g. micrometres "
                           "instead of metres) and scale the object instead, or write it with "
                           "pcvr_native.Grid.write_vdb, which keeps such scales in metadata";
                    throw GridError(msg.str());
                }
            }
        }
        file_.is.seekg(start);
    }

    /// How a tree's values are stored: bytes per value (and per value saved as half), leaf flavour.
    struct ValueLayout {
        const char* grid_type;  ///< as in the file; only the standard 5-4-3 trees
        int bytes;
        int half_bytes;  ///< bytes per value when the grid is saved as half floats
        enum Leaf { kValues, kBool, kMask } leaf;
    };

    static const ValueLayout* layout_of(const GridDescriptor& gd) {
        static const ValueLayout kLayouts[] = {
            {"Tree_float_5_4_3", 4, 2, ValueLayout::kValues}, {"Tree_double_5_4_3", 8, 2, ValueLayout::kValues},
            {"Tree_int32_5_4_3", 4, 4, ValueLayout::kValues}, {"Tree_int64_5_4_3", 8, 8, ValueLayout::kValues},
            {"Tree_vec3s_5_4_3", 12, 6, ValueLayout::kValues}, {"Tree_vec3d_5_4_3", 24, 6, ValueLayout::kValues},
            {"Tree_vec3i_5_4_3", 12, 12, ValueLayout::kValues}, {"Tree_bool_5_4_3", 1, 1, ValueLayout::kBool},
            {"Tree_mask_5_4_3", 1, 1, ValueLayout::kMask},
        };
        for (const ValueLayout& l : kLayouts)
            if (gd.gridType() == l.grid_type) return &l;
        return nullptr;
    }

    /// Walk the grid's nodes from the stream position, just after its compression flags (`compression`);
    /// returns where the grid ends. Records where each leaf's values start in `leaf_positions`, when given.
    /// The stream is left inside the grid.
    int64_t walk(const GridDescriptor& gd, uint32_t compression, std::vector<int64_t>* leaf_positions = nullptr) {
        const ValueLayout* layout = layout_of(gd);
        LayoutState st{layout, compression, gd.saveFloatAsHalf() && layout->half_bytes != layout->bytes, {}};
        {
            // Metadata and transform are already checked: let OpenVDB step over them.
            vdb::GridBase::Ptr scratch = vdb::GridBase::createGrid(gd.gridType());
            scratch->readMeta(file_.is);
            scratch->readTransform(file_.is);
        }
        walk_pos_ = file_.tell();
        leaf_positions_ = leaf_positions;
        if (!gd.isInstance()) {
            check_topology(st);
            check_buffers(st);
        }
        leaf_positions_ = nullptr;
        return walk_pos_;
    }

private:
    SizedStream& file_;

    struct LayoutState {
        const ValueLayout* layout;
        uint32_t compression;
        bool half;  ///< values stored as half floats
        /// Active-voxel count of every leaf, grouped by root child in the order readBuffers visits
        /// them: the root's std::map order (a later child with the same origin replaces the earlier).
        std::map<std::array<int32_t, 3>, std::vector<uint16_t>> leaves;
    };

    // The walk keeps its own position and steps over data with ignore(): tellg and seekg cost a
    // system call each and discard the stream's buffer.
    int64_t walk_pos_ = 0;
    std::vector<int64_t>* leaf_positions_ = nullptr;  ///< where check_buffers records each leaf, when set

    void walk_read(void* dst, int64_t n, const char* what) {
        if (n > file_.size - walk_pos_) file_.corrupt(std::string("truncated ") + what);
        file_.is.read(static_cast<char*>(dst), std::streamsize(n));
        walk_pos_ += n;
    }

    void skip(int64_t n, const char* what) {
        if (n < 0 || n > file_.size - walk_pos_) file_.corrupt(std::string("corrupt ") + what + " (size " + std::to_string(n) + ")");
        file_.is.ignore(std::streamsize(n));
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
        if (int64_t(children) * (12 + 2 * 4096) > file_.size - walk_pos_) file_.corrupt("corrupt root node (child count)");
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
                file_.corrupt("corrupt chunk size " + std::to_string(size) + " for " + std::to_string(bytes) + " bytes of values");
            skip(-size, "values");
            return;
        }
        if (st.compression & vdb::io::COMPRESS_BLOSC) {
            // blosc_decompress trusts the sizes in the chunk's own 16-byte header: they must match.
            const auto header = read_pod<std::array<uint8_t, 16>>("blosc chunk");
            if (size < 16 || int64_t(little_endian_u32(header, 4)) != bytes || int64_t(little_endian_u32(header, 12)) != size)
                file_.corrupt("corrupt blosc chunk header");
            skip(size - 16, "compressed values");
        } else {
            skip(size, "compressed values");
        }
    }
};

}  // namespace pcvr::vdb_reader
