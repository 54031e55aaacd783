/// @file grid.h
/// @brief A scalar volume read from (or written to) OpenVDB, seen by the renderer as sparse voxel blocks.
///
/// The renderer never includes OpenVDB: it walks `Grid::blocks()`, one entry per 8^3 leaf (and per
/// 8^3 chunk of an active tile), holding a pointer to the leaf's values and its active mask. A Grid
/// shares its voxels between copies; `with_index_to_world` re-places the same voxels cheaply.
/// Grids are immutable once built and safe to read from many threads.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pcvr/math.h"

namespace pcvr {

/// One bit per voxel of a VoxelBlock: bit (offset & 63) of word (offset >> 6).
using VoxelMask = std::array<uint64_t, 8>;

inline bool contains(const VoxelMask& mask, int offset) { return (mask[offset >> 6] >> (offset & 63)) & 1u; }

/// An 8^3 block of voxels in OpenVDB leaf order: offset = (x << 6) | (y << 3) | z, for x, y, z in [0, 8).
struct VoxelBlock {
    static constexpr int kDim = 8;
    static constexpr int kSize = kDim * kDim * kDim;

    std::array<int32_t, 3> origin{};    ///< index coordinates of offset 0
    const float* values = nullptr;      ///< kSize values, or nullptr for a constant block
    float constant = 0.0f;              ///< value of every voxel when values == nullptr
    VoxelMask mask{};                   ///< active voxels, bit (offset & 63) of word (offset >> 6)

    float value(int offset) const { return values ? values[offset] : constant; }
    bool active(int offset) const { return contains(mask, offset); }
};

/// The range of a block's active values, and the ranges over the voxels around it: the 3^3 blocks
/// centred on it (every voxel within 8 index units), those and the nearer halves of the next ring
/// (within 12), and the 5^3 blocks (within 16). Kernels are non-negative and sum to about one, so a
/// sample reconstructed from voxels within 8 (12, 16) index units of the block lies between
/// min(reach_min, 0) and max(reach_max, 0) (mid_, wide_), up to the kernels' ripple, whichever of
/// those voxels are left out of the sum.
struct BlockValueRange {
    float min = 0, max = 0;
    float reach_min = 0, reach_max = 0;
    float mid_min = 0, mid_max = 0;
    float wide_min = 0, wide_max = 0;
    /// The same three ranges around each of the block's eight 4^3 bricks (brick (i >> 2, j >> 2, k >> 2)
    /// as bits 2, 1, 0): over every voxel within 8, 12 and 16 index units of the brick. A block that is
    /// not transparent may still have bricks that are (the air around a CT's skin): those are left out.
    /// Empty ranges (no active voxel) are lo > hi.
    struct Bricks {
        std::array<float, 8> lo, hi;
    };
    Bricks brick_reach, brick_mid, brick_wide;
};

/// Each voxel's value range over the voxels within `radius` index units of it (a box of side 2 radius + 1),
/// inactive voxels and voxels outside the blocks counting as the background: BlockValueRange's argument
/// at one voxel, for culling single voxels whose every sample is transparent. One byte per end: level q
/// stands for lowest + q step, low ends rounded down and high ends up, so that a voxel's level range
/// holds its true one.
struct VoxelValueRanges {
    /// Larger grids get none: a byte pair per voxel for each radius asked for (128 MiB at this many blocks).
    static constexpr size_t kMostBlocks = size_t(1) << 17;
    static constexpr int kMostRadius = 16;

    int radius = 0;
    double lowest = 0, step = 1;
    std::vector<uint8_t> lo, hi;  ///< block b's voxel at `offset` is [b * VoxelBlock::kSize + offset]

    double value(int level) const { return lowest + level * step; }
};

class BrickVisibilityCache;  // src/volume/brick_visibility.h

/// The grid on a dense lattice for sampling rather than splatting (sheets filled by sampling): every
/// voxel's value less the background (0 where inactive or not finite) over the active bounding box and
/// a margin of kMargin, blurred along each axis by the three taps (w, 1 - 2w, w). Trilinear interpolation
/// of it reconstructs the volume as a kernel of per-axis variance 1/6 + 2w would (the tent's and the
/// taps'): with w from a Gaussian kernel's variance it stands in for that kernel's sum over the voxels.
/// Element (i, j, k) is index origin + (i, j, k), k fastest.
struct PrefilteredLattice {
    /// Larger grids get none (4 GiB of values). The sampler's element offsets are int32 and reach at most
    /// twice the elements; renderers bound it by the memory limit first (bytes()).
    static constexpr size_t kMostElements = size_t(1) << 30;
    static constexpr int kMargin = 2;  ///< elements beyond the active box: the taps' and the tent's reach

    /// Value ranges per brick of kBrick^3 elements, over every element within kRangeReach elements
    /// (per axis) of the brick: whatever is interpolated within that distance of a point in it lies
    /// in its brick's range. A second set over kTightRangeReach serves views whose values reach less
    /// (finer pixels, thinner sheets across the voxels): its bricks hug what may be visible more
    /// closely, so fewer values in front of an opaque surface are interpolated.
    static constexpr int kBrick = 2;
    static constexpr int kRangeReach = 6;
    static constexpr int kTightRangeReach = 4;

    std::array<int32_t, 3> origin{};
    std::array<int32_t, 3> shape{};
    std::vector<float> values;
    float blur = 0;  ///< w
    std::array<int32_t, 3> bricks{};  ///< ceil(shape / kBrick)
    /// Per brick (bi, bj, bk), bk fastest, and one more: its range as two 8-bit levels (low end in the
    /// low byte), level q standing for range_lowest + q range_step, low ends rounded down and high ends up.
    std::vector<uint16_t> ranges;
    std::vector<uint16_t> tight_ranges;  ///< the same over kTightRangeReach, in the same levels
    double range_lowest = 0, range_step = 1;
    /// Which bricks may be visible, per transfer function's visible span (src/volume/brick_visibility.h): made on
    /// first use of each span and kept with the lattice.
    std::shared_ptr<BrickVisibilityCache> visibility;

    size_t stride_i() const { return size_t(shape[1]) * size_t(shape[2]); }
    size_t stride_j() const { return size_t(shape[2]); }
    /// The elements of the lattice over an active index box ({min i, j, k, max i, j, k}).
    static size_t elements(const std::array<int32_t, 6>& box) {
        size_t n = 1;
        for (int a = 0; a < 3; ++a) n *= size_t(int64_t(box[a + 3]) - box[a] + 1 + 2 * kMargin);
        return n;
    }
    /// The bytes a lattice over `box` keeps: 4 an element for its values and 2 a brick for each of its two
    /// range sets (4.5 a voxel), besides its build's scratch of 1.5 a voxel.
    static size_t bytes(const std::array<int32_t, 6>& box) {
        size_t bricks = 1;
        for (int a = 0; a < 3; ++a) bricks *= size_t((int64_t(box[a + 3]) - box[a] + 1 + 2 * kMargin + kBrick - 1) / kBrick);
        return elements(box) * sizeof(float) + 2 * bricks * sizeof(uint16_t);
    }
};

/// How Grid::level combines 2^3 voxels into one, each kind kept for the renderer that sees the volume so.
enum class LevelReduction {
    MeanOverZero,        ///< the mean, inactive voxels counting as 0: the X-ray's levels, which keep line integrals
    MeanOverBackground,  ///< the mean, inactive voxels counting as the background: shaded rendering's
    MaxOverBackground,   ///< the largest, inactive voxels counting as the background: MIP's, which keep maxima
};

/// Level k's index coordinates to level 0's: index I of level k sits at 2^k I + (2^k - 1) / 2, the centre
/// of the voxels it stands for (Grid::level's index_to_world is the grid's times this).
inline Mat4 level_to_fine_index(int k) {
    Mat4 m;
    const double scale = double(uint64_t(1) << k);
    for (int r = 0; r < 3; ++r) {
        m.m[r][r] = scale;
        m.m[r][3] = 0.5 * (scale - 1.0);
    }
    return m;
}

/// String metadata stored with a grid in a .vdb (e.g. a converted scan's modality and units).
using GridMetadata = std::map<std::string, std::string>;

/// Codec for Grid::write_vdb. Blosc is OpenVDB's default and the fastest; zip suits readers built
/// without blosc; none is largest.
enum class VdbCompression { Blosc, Zip, None };

class Grid {
public:
    /// Build from a dense float32 array indexed [i][j][k] (C order, i slowest). Voxels equal to
    /// `background` stay inactive. Throws GridError on a singular or non-affine transform and on
    /// non-finite values.
    static Grid from_dense(const float* values, std::array<size_t, 3> shape, const Mat4& index_to_world,
                           float background, const std::string& name = "density");

    const std::string& name() const { return name_; }
    /// The file the grid came from, empty for grids built in memory.
    const std::string& source_path() const;
    const Mat4& index_to_world() const { return index_to_world_; }
    /// The same voxels under another index-to-world transform (shares memory).
    Grid with_index_to_world(const Mat4& index_to_world) const;

    uint64_t active_voxel_count() const;
    /// Inclusive index bounding box of the active voxels: {min i, min j, min k, max i, max j, max k};
    /// all zero for an empty grid.
    std::array<int32_t, 6> index_bbox() const;
    /// Minimum and maximum active value; (0, 0) for an empty grid.
    std::pair<float, float> value_range() const;
    /// The value of every inactive voxel (OpenVDB's background): air at -1000 in a CT scan in
    /// Hounsfield units. Shaded rendering reconstructs towards it beyond the active voxels.
    float background() const;
    /// The active voxels as blocks; built on first use, then cached (thread-safe).
    const std::vector<VoxelBlock>& blocks() const;
    /// One range per block of blocks(); built on first use, then cached (thread-safe).
    const std::vector<BlockValueRange>& block_value_ranges() const;
    /// Every voxel's VoxelValueRanges at `radius` (1 to VoxelValueRanges::kMostRadius); built on first use
    /// of each radius, then cached (thread-safe). Null for grids of more than VoxelValueRanges::kMostBlocks
    /// blocks.
    const VoxelValueRanges* voxel_value_ranges(int radius) const;
    /// The PrefilteredLattice of this grid with blur weight `blur` (0 to 0.25); built on first use of each
    /// weight, then cached (thread-safe). Null for grids whose lattice would exceed
    /// PrefilteredLattice::kMostElements, and for empty grids.
    const PrefilteredLattice* prefiltered_lattice(float blur) const;
    /// Level of detail `k` (0: this grid): voxel I of level k + 1 combines the 2^3 voxels 2I .. 2I + 1
    /// of level k as `reduction` says: their mean with inactive ones counting as nothing (as the X-ray
    /// sees them, so each level holds the same line integrals' mass) or as the background (as shaded
    /// rendering sees them: the density averaged, air included), or their largest value, inactive ones
    /// counting as the background (as MIP sees them). A voxel is active where any of its 2^3 is. Its
    /// index_to_world is this grid's times 2^k, moved by half a voxel of each level, so that every
    /// level's voxel centres sit at the centroids of the voxels they stand for; its background is this
    /// grid's. Built on first use, then cached with the voxels (thread-safe; copies and
    /// with_index_to_world share them; over a background of 0 both means are the same levels).
    Grid level(int k, LevelReduction reduction = LevelReduction::MeanOverZero) const;

    /// Write as a float grid named `name`: pcvr::write_vdb with this grid alone.
    void write_vdb(const std::string& path, const std::string& name) const;
    void write_vdb(const std::string& path, const std::string& name, VdbCompression compression,
                   const GridMetadata& metadata = {}) const;

    struct Data;  ///< the OpenVDB grid and the block cache (defined in grid.cpp)
    Grid(std::shared_ptr<Data> data, const Mat4& index_to_world, std::string name);

    const std::shared_ptr<Data>& data() const { return data_; }

private:
    std::shared_ptr<Data> data_;
    Mat4 index_to_world_;
    std::string name_;
};

/// One grid of a file that write_vdb writes: a float grid (one component) or a vec3s grid whose x, y and z are
/// three Grids under one index_to_world (a smoke simulation's `color` or `velocity`), on the union of their
/// active voxels.
struct VdbFileGrid {
    std::string name;
    std::vector<Grid> components;
    GridMetadata metadata;   ///< stored as string metadata on the grid, beside OpenVDB's own
};

/// Write `grids` into one .vdb file, in order, each a fog volume. Writes to a temporary file beside `path` and
/// renames it, so a failed write never leaves a half-written file. Throws GridError for grids that cannot be
/// written (no grids, a repeated name, a component count other than 1 or 3, components under different
/// transforms) and Error with the path when writing fails.
void write_vdb(const std::string& path, const std::vector<VdbFileGrid>& grids,
               VdbCompression compression = VdbCompression::Blosc);

/// Information about one grid in a file, without reading its voxels.
struct GridInfo {
    std::string name;
    std::string value_type;   ///< OpenVDB's type name: "float", "double", "int32", "vec3s", ...
    std::string grid_class;   ///< "fog volume", "level set", "staggered" or "unknown"
    uint64_t active_voxels = 0;
    GridMetadata metadata;    ///< the grid's string metadata, OpenVDB's own ("name", "class", ...) included
};

/// Read one grid. `grid_name` empty: "density" if present, else the first scalar grid.
/// double and integer grids are converted to float; level sets are converted to fog volumes
/// (density 1 inside, falling to 0 across the narrow band). Throws FileNotFound, VdbReadError or
/// GridError (unknown name: the message lists the grids that exist; vector grids: rejected).
Grid read_vdb(const std::string& path, const std::string& grid_name = "");

/// The grids of a file. Throws FileNotFound or VdbReadError.
std::vector<GridInfo> list_grids(const std::string& path);

/// Read a vector grid (vec3s, vec3d) of a .vdb file as three float Grids, its x, y and z components (named
/// "NAME.x", "NAME.y", "NAME.z"): the same voxels, tiles and transform, each component's background. Throws
/// as read_vdb, and GridError when the grid is not a vector grid.
std::array<Grid, 3> read_vdb_vector(const std::string& path, const std::string& grid_name);

}  // namespace pcvr
