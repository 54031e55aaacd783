/// @file grid_stream.h
/// @brief A grid read from its VDB file a region at a time, for volumes bigger than memory holds.
///
/// Opening one reads what the renderer plans with: the transform, the active voxels' bounds and the
/// topology (each 8^3 leaf's origin and active mask, about 100 bytes a leaf against its 2 KB of values),
/// after checking the whole grid's layout as read_vdb does, so a corrupt file fails on opening, not
/// half-way through a render. The values stay in the file. `for_each_batch` then reads them a batch of
/// 128^3 regions (OpenVDB's lower internal nodes) at a time, in file order, each batch a Grid of its
/// own that is freed before the next is read: memory is bounded by the batch size, whatever the file.
///
/// An X-ray is a sum over voxels, so rendering each batch and adding the images gives the image of the
/// whole grid (xray.h: render_xray with GridStreams). Not thread-safe: one file stream, so calls are
/// serialised; keep one GridStream per thread that reads at once.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "pcvr/grid.h"
#include "pcvr/math.h"
#include "pcvr/render_control.h"

namespace pcvr {

class GridStream {
public:
    /// Open grid `grid_name` of `path` ("density" or the first scalar grid when empty). `batch_bytes`:
    /// how many bytes of values renders read at a time (0: theirs to choose, see xray.h). Throws
    /// FileNotFound or VdbReadError (corrupt file, naming it), GridError for grids that cannot be read in
    /// parts (not float, a level set, an instance): those are read whole with read_vdb.
    static std::shared_ptr<GridStream> open(const std::string& path, const std::string& grid_name = "",
                                            uint64_t batch_bytes = 0);
    /// The batch size asked for on opening; 0: the render's choice.
    uint64_t batch_bytes() const { return batch_bytes_; }

    /// How many batches for_each_batch(batch_bytes) makes (at least one), from the topology alone.
    size_t batch_count(uint64_t batch_bytes) const;
    /// The same stream restricted to some of its batches of `batch_bytes` (indices below batch_count):
    /// renders visit only those, so processes that each render a share of the batches sum to the whole
    /// grid's image (pcvr_addon/batch splits a volume over Dask workers so). Its batch_bytes() is
    /// `batch_bytes`; it renders by batches even where the whole stream would render a coarse level.
    std::shared_ptr<GridStream> with_batches(std::vector<size_t> batches, uint64_t batch_bytes) const;
    /// The batches with_batches chose; empty for the whole stream.
    const std::vector<size_t>& only_batches() const { return only_batches_; }

    const std::string& name() const;
    const std::string& path() const;
    const Mat4& index_to_world() const { return index_to_world_; }
    /// The same stream (file, topology) under another index-to-world transform, as Grid's.
    std::shared_ptr<GridStream> with_index_to_world(const Mat4& index_to_world) const;
    float background() const;
    uint64_t active_voxel_count() const;
    /// Inclusive index bounding box of the active voxels, as Grid::index_bbox.
    std::array<int32_t, 6> index_bbox() const;
    uint64_t leaf_count() const;
    /// Bytes the leaves' values take in memory when read whole.
    uint64_t value_bytes() const;
    /// Minimum and maximum active value, as Grid::value_range: the file holds no such statistics, so
    /// the first call reads every batch (kDefaultBatchBytes at a time), later ones return it cached.
    std::pair<float, float> value_range() const;

    /// One batch of the grid: its voxels as a Grid, and how many of the stream's active voxels the
    /// batches so far (this one included) hold.
    struct Batch {
        const Grid& grid;
        uint64_t voxels_done;
    };
    /// A level-k voxel stands for 2^k voxels each way: up to 2^7 it lies within one 128^3 region, so
    /// each batch makes its part of a level on its own.
    static constexpr int kMaxLevel = 7;
    /// Level of detail k, 1 <= k <= kMaxLevel (Grid::level(k, reduction)'s voxels), made by reading every
    /// batch once and then kept with the stream (and the streams with_index_to_world makes): zoomed-out
    /// views render it from memory. It takes value_bytes() / 8^k or so. `control` may cancel the making
    /// (between batches); nothing is kept then.
    Grid level(int k, LevelReduction reduction = LevelReduction::MeanOverZero, const RenderControl* control = nullptr) const;

    /// Bytes of voxel values a batch holds when no memory limit says otherwise: more saves nothing (a
    /// batch's fixed cost in a render, its post-convolution, is a few milliseconds).
    static constexpr uint64_t kDefaultBatchBytes = uint64_t(64) << 20;

    /// Read the grid in batches of whole 128^3 regions whose leaf values take at most `batch_bytes`
    /// (a region alone may take more: up to 8 MiB), calling `visit` with each; a batch is freed when
    /// `visit` returns. Every active voxel is in exactly one batch; active tiles (constant regions) come
    /// with the region they lie in. Throws VdbReadError naming the file if it changed or fails to read.
    void for_each_batch(uint64_t batch_bytes, const std::function<void(const Batch&)>& visit) const;

    /// The index boxes (inclusive) that hold values: each leaf's 8^3 and each active tile's, from the
    /// topology alone; bricked renders (shaded/bricked_render.cpp) size their bricks from them.
    std::vector<std::array<int32_t, 6>> value_boxes() const;
    /// The voxels within `box` (inclusive index bounds) read from the file, as a Grid (every leaf that meets
    /// the box is read whole, then cut to it). Throws as for_each_batch does.
    Grid read_box(const std::array<int32_t, 6>& box) const;

    struct Impl;
    GridStream(std::shared_ptr<Impl> impl, const Mat4& index_to_world, uint64_t batch_bytes);

private:
    std::shared_ptr<Impl> impl_;  ///< shared by the streams with_index_to_world makes
    Mat4 index_to_world_;
    uint64_t batch_bytes_ = 0;
    std::vector<size_t> only_batches_;  ///< sorted; empty: every batch
};

}  // namespace pcvr
