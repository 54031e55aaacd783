/// @file grid.cpp
/// @brief pcvr::Grid: construction from dense arrays, statistics, transforms and the block view the
/// renderer walks. File I/O lives in vdb_io.cpp.
#include "pcvr/dense_grid_builder.h"
#include "volume/block_lookup.h"
#include "volume/grid_data.h"
#include "volume/prefiltered_lattice.h"
#include "volume/voxel_value_ranges.h"

#include <openvdb/tools/Count.h>
#include <openvdb/tools/Dense.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "pcvr/errors.h"

namespace pcvr {

namespace vdb = openvdb;

namespace detail {

void initialize_openvdb() {
    // A function-local static is initialised once even under concurrent first calls.
    static const bool initialized = [] {
        vdb::initialize();
        return true;
    }();
    (void)initialized;
}

namespace {

/// OpenVDB's own limit on a linear map's determinant (math/Maps.h), with a factor 2 for the
/// rounding of the map it simplifies ours into.
const double kMinVdbDeterminant = 2.0 * 3.0 * vdb::math::Tolerance<double>::value();

/// Positions must be resolved to this fraction of a voxel. Measured (tests/stress/test_scale.py):
/// an image's relative error is up to half the resolution in voxels (offset from the origin x
/// 2.2e-16 / voxel thickness), so beyond a tenth of a voxel images are off by several percent, and
/// by all of it at a voxel: a clear refusal serves the user better.
constexpr double kMaxPositionError = 0.1;

double linear_determinant(const Mat4& m) {
    return m.m[0][0] * (m.m[1][1] * m.m[2][2] - m.m[1][2] * m.m[2][1]) -
           m.m[0][1] * (m.m[1][0] * m.m[2][2] - m.m[1][2] * m.m[2][0]) +
           m.m[0][2] * (m.m[1][0] * m.m[2][1] - m.m[1][1] * m.m[2][0]);
}

/// The smallest distance between neighbouring lattice planes: how thin a voxel is, for any shear.
double voxel_thickness(const Mat4& m) {
    double widest_face = 0;
    for (int a = 0; a < 3; ++a)
        widest_face = std::max(widest_face, length(cross(m.column(a), m.column((a + 1) % 3))));
    return std::abs(linear_determinant(m)) / widest_face;
}

}  // namespace

void check_index_to_world(const Mat4& m, const std::string& context) {
    if (!m.is_finite()) throw GridError(context + ": index_to_world contains a non-finite value");
    if (!m.is_affine()) throw GridError(context + ": index_to_world is not affine (last row must be 0 0 0 1)");
    if (!m.inverse()) throw GridError(context + ": index_to_world is singular (voxels would have no volume)");
    // Double precision resolves a position x to about |x| * 2.2e-16: far from the origin, tiny voxels
    // would land on a coarser lattice than their own.
    const double offset = std::max({std::abs(m.m[0][3]), std::abs(m.m[1][3]), std::abs(m.m[2][3])});
    const double resolution = offset * std::numeric_limits<double>::epsilon(), thickness = voxel_thickness(m);
    if (resolution > kMaxPositionError * thickness) {
        std::ostringstream msg;
        msg << context << ": voxels " << thickness << " world units thick lie " << offset
            << " units from the origin, where double precision resolves positions only to " << resolution
            << " units (" << resolution / thickness << " voxels); move the volume and the camera nearer the "
            << "origin, or use a coarser world unit";
        throw GridError(msg.str());
    }
}

VdbTransform to_vdb_transform(const Mat4& m) {
    VdbTransform out;
    const double det = std::abs(linear_determinant(m));
    if (det < kMinVdbDeterminant) out.world_scale = std::pow(10.0, std::round(std::log10(det) / 3.0));
    vdb::Mat4d a;  // transposed: OpenVDB's row-vector convention
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) a(c, r) = r < 3 ? m.m[r][c] / out.world_scale : m.m[r][c];
    out.transform = std::make_shared<vdb::math::Transform>(std::make_shared<vdb::math::AffineMap>(a));
    return out;
}

Mat4 from_vdb_transform(const vdb::GridBase& grid, const std::string& context) {
    const vdb::math::Transform& xform = grid.transform();
    if (!xform.isLinear())
        throw GridError(context + " has a " + xform.mapType() +
                        " transform; only affine (linear) transforms are supported, not frustums");
    // The map's own Jacobian and image of the origin: no AffineMap is built, whose constructor
    // would refuse the tiny scales a file's ScaleMap can hold.
    const vdb::math::MapBase& map = *xform.baseMap();
    double scale = 1.0;
    if (const auto meta = grid.getMetadata<vdb::DoubleMetadata>(kWorldScaleMetadata)) {
        scale = meta->value();
        if (!std::isfinite(scale) || !(scale > 0))
            throw GridError(context + " has an invalid " + kWorldScaleMetadata + " of " + std::to_string(scale));
    }
    Mat4 m;
    const vdb::Vec3d origin = map.applyMap(vdb::Vec3d(0.0));
    for (int c = 0; c < 3; ++c) {
        vdb::Vec3d unit(0.0);
        unit[c] = 1.0;
        const vdb::Vec3d column = map.applyJacobian(unit);
        for (int r = 0; r < 3; ++r) m.m[r][c] = scale * column[r];
    }
    for (int r = 0; r < 3; ++r) m.m[r][3] = scale * origin[r];
    check_index_to_world(m, context);
    return m;
}

Grid make_grid(vdb::FloatGrid::ConstPtr grid, const std::string& source_path, const std::string& name,
               const std::string& context) {
    const Mat4 index_to_world = from_vdb_transform(*grid, context);
    return Grid(std::make_shared<Grid::Data>(std::move(grid), source_path), index_to_world, name);
}

}  // namespace detail

Grid::Data::Data(vdb::FloatGrid::ConstPtr grid, std::string path) : vdb(std::move(grid)), source_path(std::move(path)) {
    const vdb::FloatTree& tree = vdb->tree();
    active_voxel_count = tree.activeVoxelCount();
    vdb::CoordBBox bbox;
    if (active_voxel_count == 0 || !tree.evalActiveVoxelBoundingBox(bbox)) return;
    index_bbox = {bbox.min().x(), bbox.min().y(), bbox.min().z(), bbox.max().x(), bbox.max().y(), bbox.max().z()};
    const auto range = vdb::tools::minMax(tree);
    value_range = {range.min(), range.max()};
}

Grid::Grid(std::shared_ptr<Data> data, const Mat4& index_to_world, std::string name)
    : data_(std::move(data)), index_to_world_(index_to_world), name_(std::move(name)) {
    if (!data_) throw InvalidArgument("Grid: no voxel data");
}

const std::string& Grid::source_path() const { return data_->source_path; }
uint64_t Grid::active_voxel_count() const { return data_->active_voxel_count; }
std::array<int32_t, 6> Grid::index_bbox() const { return data_->index_bbox; }
std::pair<float, float> Grid::value_range() const { return data_->value_range; }
float Grid::background() const { return data_->vdb->background(); }

Grid Grid::with_index_to_world(const Mat4& index_to_world) const {
    detail::check_index_to_world(index_to_world, "grid '" + name_ + "'");
    return Grid(data_, index_to_world, name_);
}

struct DenseGridBuilder::State {
    std::array<size_t, 3> shape;
    Mat4 index_to_world;
    std::string name, context;
    vdb::FloatGrid::Ptr grid;
    size_t planes = 0;
};

DenseGridBuilder::DenseGridBuilder(std::array<size_t, 3> shape, const Mat4& index_to_world, float background,
                                   const std::string& name, const std::string& caller)
    : state_(std::make_unique<State>()) {
    detail::initialize_openvdb();
    State& s = *state_;
    s.shape = shape;
    s.index_to_world = index_to_world;
    s.name = name;
    s.context = caller + " '" + name + "'";
    detail::check_index_to_world(index_to_world, s.context);
    // Index coordinates must stay far from OpenVDB's int32 limits (node origins are rounded down).
    constexpr size_t kMaxDim = size_t(1) << 30;
    for (size_t n : shape)
        if (n > kMaxDim) throw GridError(s.context + ": array dimension " + std::to_string(n) + " is too large");
    if (!std::isfinite(background)) throw GridError(s.context + ": background is not finite");
    s.grid = vdb::FloatGrid::create(background);
}

DenseGridBuilder::~DenseGridBuilder() = default;

size_t DenseGridBuilder::planes_added() const { return state_->planes; }

void DenseGridBuilder::add_planes(const float* values, size_t count) {
    State& s = *state_;
    if (!s.grid) throw GridError(s.context + ": planes added after finish()");
    if (count > s.shape[0] - s.planes)
        throw GridError(s.context + ": " + std::to_string(s.planes + count) + " planes added to a grid of " +
                        std::to_string(s.shape[0]));
    // NaN would silently count as background in copyFromDense, infinity would poison every image.
    const size_t plane = s.shape[1] * s.shape[2], total = count * plane;
    for (size_t n = 0; n < total; ++n)
        if (!std::isfinite(values[n])) {
            const size_t k = n % s.shape[2], j = n / s.shape[2] % s.shape[1], i = s.planes + n / plane;
            throw GridError(s.context + ": values contain " + (std::isnan(values[n]) ? "NaN" : "infinity") + " at [" +
                            std::to_string(i) + ", " + std::to_string(j) + ", " + std::to_string(k) + "]");
        }
    if (total > 0) {
        const vdb::CoordBBox bbox(vdb::Coord(int(s.planes), 0, 0),
                                  vdb::Coord(int(s.planes + count) - 1, int(s.shape[1]) - 1, int(s.shape[2]) - 1));
        // LayoutZYX: k fastest, i.e. a C-order numpy array indexed [i, j, k]. copyFromDense only reads
        // the array; Dense merely lacks a const-data constructor. Leaves the slab shares with planes
        // already added start from the tree's copy, so slabs need not align with 8^3 leaves.
        const vdb::tools::Dense<float, vdb::tools::LayoutZYX> dense(bbox, const_cast<float*>(values));
        // Tolerance 0: exactly the voxels equal to the background stay inactive. Constant leaves
        // become tiles, which blocks() expands again.
        vdb::tools::copyFromDense(dense, *s.grid, 0.0f);
    }
    s.planes += count;
}

Grid DenseGridBuilder::finish() {
    State& s = *state_;
    if (!s.grid) throw GridError(s.context + ": finish() called twice");
    if (s.planes != s.shape[0])
        throw GridError(s.context + ": " + std::to_string(s.planes) + " of " + std::to_string(s.shape[0]) +
                        " planes added");
    vdb::FloatGrid::Ptr grid = std::move(s.grid);
    grid->setName(s.name);
    grid->setGridClass(vdb::GRID_FOG_VOLUME);
    // The OpenVDB grid keeps its identity transform: index_to_world is the Grid's own, in double,
    // whatever its scale, and write_vdb converts it.
    return Grid(std::make_shared<Grid::Data>(std::move(grid), std::string()), s.index_to_world, s.name);
}

Grid Grid::from_dense(const float* values, std::array<size_t, 3> shape, const Mat4& index_to_world,
                      float background, const std::string& name) {
    DenseGridBuilder builder(shape, index_to_world, background, name);
    builder.add_planes(values, shape[0]);
    return builder.finish();
}

namespace {

/// One VoxelBlock per leaf, then one constant block per 8^3 chunk of every active tile.
std::vector<VoxelBlock> build_blocks(const vdb::FloatTree& tree, const std::string& grid_name) {
    using LeafT = vdb::FloatTree::LeafNodeType;
    static_assert(LeafT::DIM == VoxelBlock::kDim, "VoxelBlock assumes OpenVDB's 8^3 leaves");
    static_assert(LeafT::NodeMaskType::WORD_COUNT == 8, "VoxelBlock::mask holds 8 64-bit words");

    // Active tiles sit above the leaf level; cap their expansion before allocating anything
    // (a single root tile already spans 4096^3 voxels).
    constexpr uint64_t kMaxTileVoxels = uint64_t(1) << 31;
    uint64_t tile_voxels = 0;
    auto tiles_begin = [&tree] {
        auto it = tree.cbeginValueOn();
        it.setMaxDepth(vdb::FloatTree::ValueOnCIter::LEAF_DEPTH - 1);
        return it;
    };
    for (auto it = tiles_begin(); it; ++it) {
        tile_voxels += it.getBoundingBox().volume();
        if (tile_voxels > kMaxTileVoxels) {
            std::ostringstream msg;
            msg << "grid '" << grid_name << "': active tiles cover more than " << kMaxTileVoxels
                << " voxels; refusing to expand them into voxel blocks";
            throw GridError(msg.str());
        }
    }

    std::vector<VoxelBlock> blocks;
    blocks.reserve(tree.leafCount() + tile_voxels / VoxelBlock::kSize);
    for (auto leaf = tree.cbeginLeaf(); leaf; ++leaf) {
        VoxelBlock b;
        const vdb::Coord o = leaf->origin();
        b.origin = {o.x(), o.y(), o.z()};
        // Same offset order as VoxelBlock: (x << 6) | (y << 3) | z.
        b.values = leaf->buffer().data();
        for (int w = 0; w < 8; ++w) b.mask[w] = leaf->getValueMask().getWord<uint64_t>(w);
        blocks.push_back(b);
    }
    for (auto it = tiles_begin(); it; ++it) {
        const vdb::CoordBBox box = it.getBoundingBox();
        VoxelBlock b;
        b.constant = *it;
        b.mask.fill(~uint64_t(0));
        // A tile spans whole 8^3 chunks (it replaces a node). 64-bit counters: it may end at INT32_MAX.
        for (int64_t x = box.min().x(); x <= box.max().x(); x += VoxelBlock::kDim)
            for (int64_t y = box.min().y(); y <= box.max().y(); y += VoxelBlock::kDim)
                for (int64_t z = box.min().z(); z <= box.max().z(); z += VoxelBlock::kDim) {
                    b.origin = {int32_t(x), int32_t(y), int32_t(z)};
                    blocks.push_back(b);
                }
    }
    return blocks;
}

struct Range {
    float lo = std::numeric_limits<float>::infinity(), hi = -std::numeric_limits<float>::infinity();
    void include(float v) { lo = std::min(lo, v), hi = std::max(hi, v); }
    void include(const Range& r) { lo = std::min(lo, r.lo), hi = std::max(hi, r.hi); }
};

/// The bricks' reaches (in bricks) of BlockValueRange::brick_reach, brick_mid and brick_wide.
constexpr int kBrickReaches[3] = {2, 3, 4};
constexpr BlockValueRange::Bricks BlockValueRange::*kBrickRanges[3] = {&BlockValueRange::brick_reach, &BlockValueRange::brick_mid,
                                                                       &BlockValueRange::brick_wide};

/// BlockValueRange's brick ranges block by block: each block's neighbourhood of 5^3 blocks as 10^3
/// bricks (the ranges of their 4^3 halves), then for each of its own eight bricks the union over the
/// bricks within 2, 3 and 4 bricks (8, 12 and 16 index units: bricks lie on a grid of 4), one axis at a
/// time. For grids whose blocks fill too little of their bounding box for build_brick_ranges_densely.
void build_brick_ranges_block_by_block(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                        const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    constexpr int kSide = 10;  // bricks per side of the neighbourhood; the block's own are 4 and 5
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        std::array<Range, kSide * kSide * kSide> local;
        const auto& o = blocks[b].origin;
        for (int dx = -2; dx <= 2; ++dx)
            for (int dy = -2; dy <= 2; ++dy)
                for (int dz = -2; dz <= 2; ++dz) {
                    const int64_t n = lookup.find({o[0] + dx * VoxelBlock::kDim, o[1] + dy * VoxelBlock::kDim, o[2] + dz * VoxelBlock::kDim});
                    if (n < 0) continue;
                    for (int h = 0; h < 8; ++h) {
                        const int x = 4 + 2 * dx + (h >> 2), y = 4 + 2 * dy + ((h >> 1) & 1), z = 4 + 2 * dz + (h & 1);
                        local[(x * kSide + y) * kSide + z] = halves[size_t(n)][h];
                    }
                }
        // Along x, then y, then z: unions over windows of 2 r + 1 bricks around the block's own 4 and 5.
        Range along_x[3][2][kSide][kSide], along_y[3][2][2][kSide];
        for (int r = 0; r < 3; ++r)
            for (int tx = 0; tx < 2; ++tx)
                for (int y = 0; y < kSide; ++y)
                    for (int z = 0; z < kSide; ++z) {
                        Range u;
                        for (int x = 4 + tx - kBrickReaches[r]; x <= 4 + tx + kBrickReaches[r]; ++x) u.include(local[(x * kSide + y) * kSide + z]);
                        along_x[r][tx][y][z] = u;
                    }
        for (int r = 0; r < 3; ++r)
            for (int tx = 0; tx < 2; ++tx)
                for (int ty = 0; ty < 2; ++ty)
                    for (int z = 0; z < kSide; ++z) {
                        Range u;
                        for (int y = 4 + ty - kBrickReaches[r]; y <= 4 + ty + kBrickReaches[r]; ++y) u.include(along_x[r][tx][y][z]);
                        along_y[r][tx][ty][z] = u;
                    }
        for (int r = 0; r < 3; ++r)
            for (int h = 0; h < 8; ++h) {
                const int tx = h >> 2, ty = (h >> 1) & 1, tz = h & 1;
                Range u;
                for (int z = 4 + tz - kBrickReaches[r]; z <= 4 + tz + kBrickReaches[r]; ++z) u.include(along_y[r][tx][ty][z]);
                (ranges[b].*kBrickRanges[r]).lo[h] = u.lo;
                (ranges[b].*kBrickRanges[r]).hi[h] = u.hi;
            }
    });
}

/// Each of `cells`' lines along `axis` (of a box `sides` cells, the last axis fastest) replaced by the unions
/// over windows of 2 `reach` + 1 cells around each cell, cut at the box's faces.
void unite_along(std::vector<Range>& cells, const std::array<int64_t, 3>& sides, int axis, int reach) {
    const int64_t stride = axis == 0 ? sides[1] * sides[2] : axis == 1 ? sides[2] : 1;
    const int64_t length = sides[axis];
    const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;  // the other two axes
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, sides[u] * sides[v]), [&](const tbb::blocked_range<int64_t>& lines) {
        std::vector<Range> line(static_cast<size_t>(length));
        for (int64_t l = lines.begin(); l < lines.end(); ++l) {
            std::array<int64_t, 3> at{0, 0, 0};
            at[u] = l / sides[v], at[v] = l % sides[v];
            const int64_t first = (at[0] * sides[1] + at[1]) * sides[2] + at[2];
            for (int64_t c = 0; c < length; ++c) line[size_t(c)] = cells[size_t(first + c * stride)];
            for (int64_t c = 0; c < length; ++c) {
                Range u_range;
                for (int64_t w = std::max<int64_t>(0, c - reach); w <= std::min(length - 1, c + reach); ++w) u_range.include(line[size_t(w)]);
                cells[size_t(first + c * stride)] = u_range;
            }
        }
    });
}

/// BlockValueRange's brick ranges over the blocks' bounding box at once: the halves laid out on a dense
/// lattice of bricks, then the windows' unions one axis at a time for each reach (in place: one lattice
/// of 8 ranges a block, 64 bytes). A tenth of the block-by-block work, which redoes each brick's unions
/// for every block whose neighbourhood holds it (the sum of a streamed CT's bricks' ranges took 3.8 s of 9).
void build_brick_ranges_densely(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                                const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    const std::array<int64_t, 3> first = lookup.first_block(), per_side = lookup.blocks_per_side();
    const std::array<int64_t, 3> sides{2 * per_side[0], 2 * per_side[1], 2 * per_side[2]};
    auto cell = [&](size_t b, int h) {
        const auto& o = blocks[b].origin;
        const int64_t x = 2 * (o[0] / VoxelBlock::kDim - first[0]) + (h >> 2), y = 2 * (o[1] / VoxelBlock::kDim - first[1]) + ((h >> 1) & 1),
                      z = 2 * (o[2] / VoxelBlock::kDim - first[2]) + (h & 1);
        return size_t((x * sides[1] + y) * sides[2] + z);
    };
    std::vector<Range> cells;
    for (int r = 0; r < 3; ++r) {
        cells.assign(size_t(sides[0] * sides[1] * sides[2]), Range{});
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            for (int h = 0; h < 8; ++h) cells[cell(b, h)] = halves[b][h];
        });
        // x, then y, then z, as the block-by-block build: min and max are exact, so the order is free anyway.
        for (int axis = 0; axis < 3; ++axis) unite_along(cells, sides, axis, kBrickReaches[r]);
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            for (int h = 0; h < 8; ++h) {
                (ranges[b].*kBrickRanges[r]).lo[h] = cells[cell(b, h)].lo;
                (ranges[b].*kBrickRanges[r]).hi[h] = cells[cell(b, h)].hi;
            }
        });
    }
}

/// BlockValueRange's brick ranges: densely where the blocks fill at least half their bounding box (as a
/// brick of a stream, or a scan, does; the lattice is then at most 128 bytes a block), else block by block.
void build_brick_ranges(const std::vector<VoxelBlock>& blocks, const std::vector<std::array<Range, 8>>& halves,
                        const BlockLookup& lookup, std::vector<BlockValueRange>& ranges) {
    const std::array<int64_t, 3> per_side = lookup.blocks_per_side();
    if (lookup.dense() && uint64_t(per_side[0] * per_side[1] * per_side[2]) <= 2 * uint64_t(blocks.size()))
        build_brick_ranges_densely(blocks, halves, lookup, ranges);
    else
        build_brick_ranges_block_by_block(blocks, halves, lookup, ranges);
}

/// Each block's own value range, then the unions over the 3^3 blocks around it, over the voxels
/// within 12 index units (from the halves of the blocks 2 away that face it) and over the 5^3 blocks;
/// and its bricks' (build_brick_ranges).
std::vector<BlockValueRange> build_value_ranges(const std::vector<VoxelBlock>& blocks) {
    std::vector<BlockValueRange> ranges(blocks.size());
    // The ranges of each block's eight 4^3 halves, (i >> 2, j >> 2, k >> 2) as bits 2, 1, 0.
    std::vector<std::array<Range, 8>> halves(blocks.size());
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        const VoxelBlock& block = blocks[b];
        Range whole;
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const float v = block.value(offset);
            if (!block.active(offset) || !std::isfinite(v)) continue;  // the splats skip these too
            halves[b][((offset >> 8) & 1) << 2 | ((offset >> 5) & 1) << 1 | ((offset >> 2) & 1)].include(v);
            whole.include(v);
        }
        if (!(whole.lo <= whole.hi)) whole.lo = whole.hi = 0.0f;
        ranges[b].min = whole.lo;
        ranges[b].max = whole.hi;
    });
    // Every pass below looks up each block's neighbours: through the dense array where the grid allows it
    // (the hash map's 150 lookups a block were most of a streamed brick's range building).
    const BlockLookup lookup(blocks);
    // Each ring is the union of the previous ring's ranges over the 27 blocks around.
    auto widen = [&](auto inner_lo, auto inner_hi, auto outer_lo, auto outer_hi) {
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
            float lo = ranges[b].*inner_lo, hi = ranges[b].*inner_hi;
            const auto& o = blocks[b].origin;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dz = -1; dz <= 1; ++dz) {
                        const int64_t n = lookup.find({o[0] + dx * VoxelBlock::kDim, o[1] + dy * VoxelBlock::kDim,
                                                       o[2] + dz * VoxelBlock::kDim});
                        if (n < 0) continue;
                        lo = std::min(lo, ranges[size_t(n)].*inner_lo);
                        hi = std::max(hi, ranges[size_t(n)].*inner_hi);
                    }
            ranges[b].*outer_lo = lo;
            ranges[b].*outer_hi = hi;
        });
    };
    widen(&BlockValueRange::min, &BlockValueRange::max, &BlockValueRange::reach_min, &BlockValueRange::reach_max);
    widen(&BlockValueRange::reach_min, &BlockValueRange::reach_max, &BlockValueRange::wide_min, &BlockValueRange::wide_max);
    build_brick_ranges(blocks, halves, lookup, ranges);
    // Within 12: the 3^3 ring, and of the blocks two away along an axis only the half facing this one,
    // which is along each axis the bricks 3 before the block's first to 4 after: the union of its own
    // bricks' ranges within 12 (those over the ring's halves lie within the ring's range).
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        Range within{ranges[b].reach_min, ranges[b].reach_max};
        for (int h = 0; h < 8; ++h) within.include(Range{ranges[b].brick_mid.lo[h], ranges[b].brick_mid.hi[h]});
        ranges[b].mid_min = within.lo;
        ranges[b].mid_max = within.hi;
    });
    return ranges;
}

}  // namespace

const std::vector<BlockValueRange>& Grid::block_value_ranges() const {
    const std::vector<VoxelBlock>& all = blocks();
    if (!data_->ranges_ready.load(std::memory_order_acquire)) {
        std::lock_guard<std::mutex> lock(data_->ranges_mutex);
        if (!data_->ranges_ready.load(std::memory_order_relaxed)) {
            data_->ranges = build_value_ranges(all);
            data_->ranges_ready.store(true, std::memory_order_release);
        }
    }
    return data_->ranges;
}

const VoxelValueRanges* Grid::voxel_value_ranges(int radius) const {
    const std::vector<VoxelBlock>& all = blocks();
    if (all.size() > VoxelValueRanges::kMostBlocks) return nullptr;
    std::lock_guard<std::mutex> lock(data_->voxel_ranges_mutex);
    std::unique_ptr<VoxelValueRanges>& ranges = data_->voxel_ranges[radius];
    if (!ranges) ranges = std::make_unique<VoxelValueRanges>(build_voxel_value_ranges(all, background(), radius));
    return ranges.get();
}

const PrefilteredLattice* Grid::prefiltered_lattice(float blur) const {
    if (active_voxel_count() == 0) return nullptr;
    const std::array<int32_t, 6> box = index_bbox();
    if (PrefilteredLattice::elements(box) > PrefilteredLattice::kMostElements) return nullptr;
    const std::vector<VoxelBlock>& all = blocks();
    std::lock_guard<std::mutex> lock(data_->lattices_mutex);
    std::unique_ptr<PrefilteredLattice>& lattice = data_->lattices[blur];
    if (!lattice) lattice = std::make_unique<PrefilteredLattice>(build_prefiltered_lattice(all, box, background(), blur));
    return lattice.get();
}

namespace {

/// The next level of detail's mean voxels (see Grid::level): each active voxel adds an eighth of its
/// departure from `inactive` (what the inactive ones count as) to the voxel of half its index (rounded
/// down), in float (at most eight terms each), and the coarse voxels get `inactive` back. Voxels equal
/// to `inactive` change nothing and are left out.
vdb::FloatGrid::Ptr halve_by_mean(const std::vector<VoxelBlock>& blocks, float inactive, float background) {
    auto coarse = vdb::FloatGrid::create(background);
    auto acc = coarse->getAccessor();
    for (const VoxelBlock& block : blocks)
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const float v = block.value(offset);
            if (!block.active(offset) || v == inactive || !std::isfinite(v)) continue;
            const vdb::Coord at((block.origin[0] + (offset >> 6)) >> 1, (block.origin[1] + ((offset >> 3) & 7)) >> 1,
                                (block.origin[2] + (offset & 7)) >> 1);
            acc.setValue(at, (acc.isValueOn(at) ? acc.getValue(at) : 0.0f) + 0.125f * (v - inactive));
        }
    if (inactive != 0.0f)
        for (auto leaf = coarse->tree().beginLeaf(); leaf; ++leaf)
            for (auto voxel = leaf->beginValueOn(); voxel; ++voxel) voxel.setValue(*voxel + inactive);
    return coarse;
}

/// The next level of detail's largest voxels (see Grid::level): each active voxel raises the voxel of
/// half its index to its value, and a coarse voxel with an inactive one among its 2^3 (looked up in
/// `fine`) to the background.
vdb::FloatGrid::Ptr halve_by_max(const std::vector<VoxelBlock>& blocks, const vdb::FloatTree& fine, float background) {
    auto coarse = vdb::FloatGrid::create(background);
    auto acc = coarse->getAccessor();
    for (const VoxelBlock& block : blocks)
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const float v = block.value(offset);
            if (!block.active(offset) || !std::isfinite(v)) continue;
            const vdb::Coord at((block.origin[0] + (offset >> 6)) >> 1, (block.origin[1] + ((offset >> 3) & 7)) >> 1,
                                (block.origin[2] + (offset & 7)) >> 1);
            acc.setValue(at, acc.isValueOn(at) ? std::max(acc.getValue(at), v) : v);
        }
    vdb::tree::ValueAccessor<const vdb::FloatTree> children(fine);
    for (auto leaf = coarse->tree().beginLeaf(); leaf; ++leaf)
        for (auto voxel = leaf->beginValueOn(); voxel; ++voxel) {
            const vdb::Coord first = voxel.getCoord() << 1;
            bool all_active = true;
            for (int child = 0; child < 8 && all_active; ++child)
                all_active = children.isValueOn(first.offsetBy(child >> 2, (child >> 1) & 1, child & 1));
            if (!all_active) voxel.setValue(std::max(*voxel, background));
        }
    return coarse;
}

}  // namespace

Grid Grid::level(int k, LevelReduction reduction) const {
    if (k < 0) throw InvalidArgument("grid '" + name_ + "': level must be 0 (the grid itself) or more");
    if (k == 0) return *this;
    // Over a background of 0 the two means are the same voxels: build and cache them once.
    if (reduction == LevelReduction::MeanOverBackground && background() == 0.0f) reduction = LevelReduction::MeanOverZero;
    std::shared_ptr<Data> next;
    {
        std::lock_guard<std::mutex> lock(data_->coarser_mutex);
        std::shared_ptr<Data>& coarser = data_->coarser[size_t(reduction)];
        if (!coarser) {
            auto grid = reduction == LevelReduction::MaxOverBackground
                            ? halve_by_max(blocks(), data_->vdb->tree(), background())
                            : halve_by_mean(blocks(), reduction == LevelReduction::MeanOverBackground ? background() : 0.0f,
                                            background());
            grid->setName(name_);
            grid->setGridClass(vdb::GRID_FOG_VOLUME);
            coarser = std::make_shared<Data>(std::move(grid), std::string());
        }
        next = coarser;
    }
    return Grid(std::move(next), index_to_world_ * level_to_fine_index(1), name_).level(k - 1, reduction);
}

const std::vector<VoxelBlock>& Grid::blocks() const {
    // Double-checked: after the first build every caller takes only the atomic load.
    if (!data_->blocks_ready.load(std::memory_order_acquire)) {
        std::lock_guard<std::mutex> lock(data_->blocks_mutex);
        if (!data_->blocks_ready.load(std::memory_order_relaxed)) {
            data_->blocks = build_blocks(data_->vdb->tree(), name_);
            data_->blocks_ready.store(true, std::memory_order_release);
        }
    }
    return data_->blocks;
}

}  // namespace pcvr
