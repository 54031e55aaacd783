/// @file grid_stream.cpp
/// @brief GridStream: a VDB grid's topology in memory, its values read a batch of 128^3 regions at a time.
#include "pcvr/grid_stream.h"

#include "volume/grid_data.h"
#include "volume/vdb_leaf_reader.h"
#include "volume/vdb_reader.h"

#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
#include <vector>

#include "pcvr/errors.h"

namespace pcvr {

namespace vdb = openvdb;
using namespace vdb_reader;

namespace {

using UpperT = vdb::FloatTree::RootNodeType::ChildNodeType;
using LowerT = UpperT::ChildNodeType;
using LeafT = vdb::FloatTree::LeafNodeType;
constexpr uint64_t kLeafBytes = sizeof(float) * LeafT::SIZE;

/// What tells a file apart from its rewritten self: a stream opened on one file reads only that one.
struct FileIdentity {
    uintmax_t size = 0;
    std::filesystem::file_time_type modified;

    static FileIdentity of(const std::string& path) {
        std::error_code ec;
        FileIdentity id{std::filesystem::file_size(path, ec), std::filesystem::last_write_time(path, ec)};
        if (ec) throw VdbReadError("cannot read " + vdb_reader::quoted(path) + ": " + ec.message());
        return id;
    }
    bool operator==(const FileIdentity& o) const { return size == o.size && modified == o.modified; }
};

/// An active tile above the leaves: a constant 8^3 (level 1), 128^3 (2) or 4096^3 (3) block.
struct Tile {
    vdb::Index level;
    vdb::Coord origin;
    float value;
    uint64_t voxels;
};

/// A 128^3 region: a lower internal node, its first leaf in the file's leaf order and its active
/// tiles; or one tile that spans a region or more. A batch takes whole regions, so a level-k voxel
/// (k <= 7) never has its voxels in two batches.
struct Region {
    const LowerT* node = nullptr;  ///< null for a region that is one tile
    size_t first_leaf = 0;
    uint64_t leaves = 0;
    std::vector<Tile> tiles;
};

}  // namespace

struct GridStream::Impl {
    std::string path, name;
    FileIdentity identity;
    std::unique_ptr<Reader> reader;  ///< the open file; its stream is tagged with this grid's settings
    vdb::FloatGrid::Ptr topology;    ///< leaves without values
    bool half = false;               ///< values stored as half floats
    Mat4 file_index_to_world;        ///< as the file places it
    uint64_t active_voxels = 0;
    std::array<int32_t, 6> bbox{};
    std::vector<Region> regions;     ///< in the file's (and the tree's) leaf order
    std::vector<int64_t> leaf_positions;  ///< where each leaf's record starts, in that order
    std::mutex mutex;                ///< one stream: one batch walk at a time
    std::mutex range_mutex;
    std::optional<std::pair<float, float>> value_range;  ///< once value_range() has read it
    std::mutex levels_mutex;
    std::map<std::pair<int, LevelReduction>, std::shared_ptr<Grid::Data>> levels;  ///< those level() has made

    /// `only` (sorted, or empty for all): the batches to read and visit; the others are planned, not read.
    void for_each_batch(uint64_t batch_bytes, const Mat4& index_to_world, const std::function<void(const Batch&)>& visit,
                        const std::vector<size_t>& only = {});

    /// The region after the batch that starts at region `next`: whole regions up to `batch_bytes`.
    size_t batch_end(size_t next, uint64_t batch_bytes) const {
        uint64_t bytes = 0;
        for (; next < regions.size(); ++next) {
            const uint64_t region_bytes = regions[next].leaves * kLeafBytes;
            if (bytes > 0 && bytes + region_bytes > batch_bytes) break;
            bytes += region_bytes;
        }
        return next;
    }

    /// Throws VdbReadError where the file is no longer the one opened.
    void check_unchanged() const {
        if (!(FileIdentity::of(path) == identity))
            throw VdbReadError("cannot read " + vdb_reader::quoted(path) + ": the file changed since " + vdb_reader::quoted(name) +
                               " was opened from it; open it again");
    }

    /// An empty float grid with the stream's background, for a batch.
    vdb::FloatGrid::Ptr empty_batch() const { return vdb::FloatGrid::create(topology->background()); }

    /// Read regions [first, last) into `batch`, their leaves on all threads; returns their active voxels.
    uint64_t add_regions(size_t first, size_t last, vdb::FloatTree& batch) {
        std::vector<std::unique_ptr<LeafT>> leaves;
        uint64_t voxels = 0;
        for (size_t r = first; r < last; ++r) {
            for (const Tile& tile : regions[r].tiles) {
                batch.addTile(tile.level, tile.origin, tile.value, true);
                voxels += tile.voxels;
            }
            if (!regions[r].node) continue;
            for (auto src = regions[r].node->cbeginChildOn(); src; ++src) {
                auto leaf = std::make_unique<LeafT>(vdb::PartialCreate(), src->origin(), topology->background());
                leaf->setValueMask(src->getValueMask());
                voxels += src->onVoxelCount();
                leaves.push_back(std::move(leaf));
            }
        }
        // Regions with leaves hold consecutive leaves: the batch's first leaf starts the run.
        const auto with_leaves = std::find_if(regions.begin() + first, regions.begin() + last,
                                              [](const Region& r) { return r.leaves > 0; });
        std::vector<size_t> numbers(leaves.size());
        std::iota(numbers.begin(), numbers.end(), with_leaves != regions.begin() + last ? with_leaves->first_leaf : 0);
        read_into(batch, leaves, numbers);
        return voxels;
    }

    /// Fill `leaves` (numbers[i]: leaves[i]'s place in the file's leaf order) and move them into `tree`.
    void read_into(vdb::FloatTree& tree, std::vector<std::unique_ptr<LeafT>>& leaves, const std::vector<size_t>& numbers) {
        std::vector<LeafT*> targets;
        for (auto& leaf : leaves) targets.push_back(leaf.get());
        if (!targets.empty()) read_leaves_parallel(reader->file(), targets, numbers, leaf_positions.data(), half);
        for (auto& leaf : leaves) tree.addLeaf(leaf.release());
    }

    /// Reads the leaves that meet `box`, and the active tiles' voxels within it: the voxels within it.
    vdb::FloatGrid::Ptr read_box(const vdb::CoordBBox& box) {
        vdb::FloatGrid::Ptr grid = empty_batch();
        std::vector<std::unique_ptr<LeafT>> leaves;
        std::vector<size_t> numbers;
        for (const Region& region : regions) {
            for (const Tile& tile : region.tiles) {
                vdb::CoordBBox part = tile_box(tile);
                part.intersect(box);
                if (!part.empty()) grid->tree().fill(part, tile.value, true);
            }
            if (!region.node || !region.node->getNodeBoundingBox().hasOverlap(box)) continue;
            size_t number = region.first_leaf;
            for (auto src = region.node->cbeginChildOn(); src; ++src, ++number) {
                if (!src->getNodeBoundingBox().hasOverlap(box)) continue;
                auto leaf = std::make_unique<LeafT>(vdb::PartialCreate(), src->origin(), topology->background());
                leaf->setValueMask(src->getValueMask());
                leaves.push_back(std::move(leaf));
                numbers.push_back(number);
            }
        }
        read_into(grid->tree(), leaves, numbers);
        // The leaves' voxels beyond the box would only cost work; within the active voxels' bounds, as the
        // cut walks its box's tiles.
        vdb::CoordBBox cut = box;
        cut.intersect(vdb::CoordBBox({bbox[0], bbox[1], bbox[2]}, {bbox[3], bbox[4], bbox[5]}));
        grid->clip(cut);
        grid->setName(name);
        return grid;
    }

    static vdb::CoordBBox tile_box(const Tile& tile) {
        const int dim = tile.level == 1 ? LeafT::DIM : tile.level == 2 ? LowerT::DIM : UpperT::DIM;
        return vdb::CoordBBox::createCube(tile.origin, dim);
    }
};

GridStream::GridStream(std::shared_ptr<Impl> impl, const Mat4& index_to_world, uint64_t batch_bytes)
    : impl_(std::move(impl)), index_to_world_(index_to_world), batch_bytes_(batch_bytes) {}

std::shared_ptr<GridStream> GridStream::open(const std::string& path, const std::string& grid_name, uint64_t batch_bytes) {
    detail::initialize_openvdb();
    return guard_read(path, [&] {
        auto impl = std::make_shared<Impl>();
        impl->path = path;
        impl->identity = FileIdentity::of(path);
        impl->reader = std::make_unique<Reader>(path);
        const size_t index = choose_grid(*impl->reader, grid_name);
        const Entry& entry = impl->reader->entries()[index];
        impl->name = Reader::display_name(entry);
        const std::string context = "grid " + vdb_reader::quoted(impl->name) + " in " + vdb_reader::quoted(path);
        Reader::Topology topology = impl->reader->read_topology(index);
        impl->topology = topology.grid;
        impl->half = entry.gd.saveFloatAsHalf();
        impl->file_index_to_world = detail::from_vdb_transform(*impl->topology, context);

        const vdb::FloatTree& tree = impl->topology->tree();
        impl->active_voxels = tree.activeVoxelCount();
        vdb::CoordBBox box;
        if (impl->active_voxels > 0 && tree.evalActiveVoxelBoundingBox(box))
            impl->bbox = {box.min().x(), box.min().y(), box.min().z(), box.max().x(), box.max().y(), box.max().z()};
        // Regions in the order readBuffers (and so the file) visits leaves: the root's children by
        // origin, then each internal node's children by index.
        size_t leaf = 0;
        for (auto upper = tree.root().cbeginChildOn(); upper; ++upper) {
            for (auto lower = upper->cbeginChildOn(); lower; ++lower) {
                Region region{&*lower, leaf, lower->getChildMask().countOn(), {}};
                for (auto tile = lower->cbeginValueOn(); tile; ++tile)
                    region.tiles.push_back({1, tile.getCoord(), *tile, LeafT::NUM_VOXELS});
                if (region.leaves == 0 && region.tiles.empty()) continue;
                leaf += region.leaves;
                impl->regions.push_back(std::move(region));
            }
            for (auto tile = upper->cbeginValueOn(); tile; ++tile)
                impl->regions.push_back({nullptr, 0, 0, {{2, tile.getCoord(), *tile, LowerT::NUM_VOXELS}}});
        }
        for (auto tile = tree.root().cbeginValueOn(); tile; ++tile)
            impl->regions.push_back({nullptr, 0, 0, {{3, tile.getCoord(), *tile, UpperT::NUM_VOXELS}}});
        const Mat4 index_to_world = impl->file_index_to_world;
        impl->leaf_positions = std::move(topology.leaf_positions);
        return std::make_shared<GridStream>(std::move(impl), index_to_world, batch_bytes);
    });
}

const std::string& GridStream::name() const { return impl_->name; }
const std::string& GridStream::path() const { return impl_->path; }
std::shared_ptr<GridStream> GridStream::with_index_to_world(const Mat4& index_to_world) const {
    detail::check_index_to_world(index_to_world, "grid '" + impl_->name + "'");
    auto moved = std::make_shared<GridStream>(impl_, index_to_world, batch_bytes_);
    moved->only_batches_ = only_batches_;
    return moved;
}
float GridStream::background() const { return impl_->topology->background(); }
uint64_t GridStream::active_voxel_count() const { return impl_->active_voxels; }
std::array<int32_t, 6> GridStream::index_bbox() const { return impl_->bbox; }
uint64_t GridStream::leaf_count() const { return impl_->topology->tree().leafCount(); }
uint64_t GridStream::value_bytes() const { return leaf_count() * kLeafBytes; }

std::pair<float, float> GridStream::value_range() const {
    std::lock_guard<std::mutex> lock(impl_->range_mutex);
    if (!impl_->value_range) {
        std::pair<float, float> range{0.0f, 0.0f};
        bool any = false;
        // Every batch, also for a stream of some batches only: the range is the grid's.
        impl_->for_each_batch(kDefaultBatchBytes, index_to_world_, [&](const Batch& batch) {
            if (batch.grid.active_voxel_count() == 0) return;
            const auto [lo, hi] = batch.grid.value_range();
            range = any ? std::pair<float, float>{std::min(range.first, lo), std::max(range.second, hi)} : std::pair<float, float>{lo, hi};
            any = true;
        });
        impl_->value_range = range;
    }
    return *impl_->value_range;
}

void GridStream::Impl::for_each_batch(uint64_t batch_bytes, const Mat4& index_to_world,
                                      const std::function<void(const Batch&)>& visit, const std::vector<size_t>& only) {
    Impl& s = *this;
    std::lock_guard<std::mutex> lock(s.mutex);
    guard_read(s.path, [&] { s.check_unchanged(); });
    uint64_t voxels_done = 0;
    size_t next = 0;
    // An empty grid still makes one (empty) batch.
    for (size_t index = 0; index == 0 || next < s.regions.size(); ++index) {
        const size_t first_region = next;
        next = s.batch_end(next, batch_bytes);
        if (!only.empty() && !std::binary_search(only.begin(), only.end(), index)) continue;
        vdb::FloatGrid::Ptr batch = s.empty_batch();
        guard_read(s.path, [&] {
            if (next > first_region) voxels_done += s.add_regions(first_region, next, batch->tree());
        });
        batch->setName(s.name);
        const Grid grid(std::make_shared<Grid::Data>(std::move(batch), s.path), index_to_world, s.name);
        visit(Batch{grid, voxels_done});
    }
}

void GridStream::for_each_batch(uint64_t batch_bytes, const std::function<void(const Batch&)>& visit) const {
    if (!only_batches_.empty() && batch_bytes != batch_bytes_)
        throw InvalidArgument("grid '" + impl_->name + "': its batches were chosen at " + std::to_string(batch_bytes_) +
                              " bytes a batch, not " + std::to_string(batch_bytes));
    impl_->for_each_batch(batch_bytes, index_to_world_, visit, only_batches_);
}

std::vector<std::array<int32_t, 6>> GridStream::value_boxes() const {
    std::vector<std::array<int32_t, 6>> boxes;
    auto add = [&](const vdb::CoordBBox& b) {
        boxes.push_back({b.min().x(), b.min().y(), b.min().z(), b.max().x(), b.max().y(), b.max().z()});
    };
    for (const Region& region : impl_->regions) {
        for (const Tile& tile : region.tiles) add(Impl::tile_box(tile));
        if (region.node)
            for (auto leaf = region.node->cbeginChildOn(); leaf; ++leaf) add(leaf->getNodeBoundingBox());
    }
    return boxes;
}

Grid GridStream::read_box(const std::array<int32_t, 6>& box) const {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    const vdb::CoordBBox within({box[0], box[1], box[2]}, {box[3], box[4], box[5]});
    vdb::FloatGrid::Ptr grid;
    guard_read(impl_->path, [&] {
        impl_->check_unchanged();
        grid = impl_->read_box(within);
    });
    return Grid(std::make_shared<Grid::Data>(std::move(grid), impl_->path), index_to_world_, impl_->name);
}

size_t GridStream::batch_count(uint64_t batch_bytes) const {
    size_t count = 0;
    for (size_t next = 0; count == 0 || next < impl_->regions.size(); ++count) next = impl_->batch_end(next, batch_bytes);
    return count;
}

std::shared_ptr<GridStream> GridStream::with_batches(std::vector<size_t> batches, uint64_t batch_bytes) const {
    if (batch_bytes == 0) throw InvalidArgument("grid '" + impl_->name + "': batch_bytes must be positive");
    const size_t count = batch_count(batch_bytes);
    std::sort(batches.begin(), batches.end());
    batches.erase(std::unique(batches.begin(), batches.end()), batches.end());
    if (batches.empty() || batches.back() >= count)
        throw InvalidArgument("grid '" + impl_->name + "': batches must be some of 0 to " + std::to_string(count - 1) +
                              " (" + std::to_string(count) + " batches of " + std::to_string(batch_bytes) + " bytes)");
    auto subset = std::make_shared<GridStream>(impl_, index_to_world_, batch_bytes);
    subset->only_batches_ = std::move(batches);
    return subset;
}

Grid GridStream::level(int k, LevelReduction reduction, const RenderControl* control) const {
    if (k < 1 || k > kMaxLevel)
        throw InvalidArgument("grid '" + impl_->name + "': a stream's level must be from 1 to " + std::to_string(kMaxLevel));
    std::shared_ptr<Grid::Data> data;
    {
        std::lock_guard<std::mutex> lock(impl_->levels_mutex);
        auto& cached = impl_->levels[{k, reduction}];
        if (!cached) {
            // Each batch's level holds the level's voxels over the batch's regions, and no other batch has
            // voxels there: merging the active voxels makes the whole level.
            vdb::FloatGrid::Ptr merged = impl_->empty_batch();
            impl_->for_each_batch(kDefaultBatchBytes, impl_->file_index_to_world, [&](const Batch& batch) {
                if (control) control->throw_if_cancelled();
                vdb::FloatGrid::Ptr part = batch.grid.level(k, reduction).data()->vdb->deepCopy();
                merged->tree().merge(part->tree(), vdb::MERGE_ACTIVE_STATES);
            });
            merged->setName(impl_->name);
            cached = std::make_shared<Grid::Data>(std::move(merged), impl_->path);
        }
        data = cached;
    }
    return Grid(std::move(data), index_to_world_ * level_to_fine_index(k), impl_->name);
}

}  // namespace pcvr
