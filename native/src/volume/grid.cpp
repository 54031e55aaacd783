/// @file grid.cpp
/// @brief pcvr::Grid: construction from dense arrays, statistics, transforms and the block view the
/// renderer walks. File I/O lives in vdb_io.cpp.
#include "pcvr/dense_grid_builder.h"
#include "volume/block_value_ranges.h"
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

}  // namespace

const std::vector<BlockValueRange>& Grid::block_value_ranges() const {
    const std::vector<VoxelBlock>& all = blocks();
    if (!data_->ranges_ready.load(std::memory_order_acquire)) {
        std::lock_guard<std::mutex> lock(data_->ranges_mutex);
        if (!data_->ranges_ready.load(std::memory_order_relaxed)) {
            data_->ranges = build_block_value_ranges(all);
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
