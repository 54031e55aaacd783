/// @file grid_data.h
/// @brief Grid::Data, the OpenVDB grid behind a pcvr::Grid, and the helpers grid.cpp and vdb_io.cpp share.
///
/// Private to the two grid translation units: everything else sees only pcvr/grid.h, so the rendering
/// core never pays for OpenVDB's headers.
#pragma once

#include <openvdb/openvdb.h>

#include <array>
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "pcvr/grid.h"

namespace pcvr {

struct Grid::Data {
    /// Never modified after construction, so any number of threads may read it. Leaf buffers are
    /// fully loaded (no delayed loading): VoxelBlock::values point straight into them. No
    /// ValueAccessor is kept here: accessors cache nodes and are not thread-safe, one per thread.
    openvdb::FloatGrid::ConstPtr vdb;
    std::string source_path;  ///< empty for grids built in memory

    // Statistics over the active voxels (tiles included), computed once at construction.
    uint64_t active_voxel_count = 0;
    std::array<int32_t, 6> index_bbox{};
    std::pair<float, float> value_range{0.0f, 0.0f};

    // Block cache, built by the first call to Grid::blocks(). A mutex rather than std::call_once:
    // a failed build (absurd tile expansion) throws, and call_once with exceptions is unreliable
    // on some libstdc++ targets.
    std::mutex blocks_mutex;
    std::atomic<bool> blocks_ready{false};
    std::vector<VoxelBlock> blocks;
    std::mutex ranges_mutex;
    std::atomic<bool> ranges_ready{false};
    std::vector<BlockValueRange> ranges;
    std::mutex voxel_ranges_mutex;
    /// Grid::voxel_value_ranges by radius (built under the mutex; entries never move once made).
    std::map<int, std::unique_ptr<VoxelValueRanges>> voxel_ranges;
    std::mutex lattices_mutex;
    /// Grid::prefiltered_lattice by blur weight (built under the mutex; entries never move once made).
    std::map<float, std::unique_ptr<PrefilteredLattice>> lattices;
    std::mutex coarser_mutex;
    /// The next level of detail, built by the first Grid::level(k > 0) of each LevelReduction (indexed by it).
    std::array<std::shared_ptr<Data>, 3> coarser;

    Data(openvdb::FloatGrid::ConstPtr grid, std::string path);
};

namespace detail {

/// openvdb::initialize() exactly once per process, from any thread.
void initialize_openvdb();

/// Throws GridError (prefixed with `context`) unless `m` is finite, affine and invertible.
void check_index_to_world(const Mat4& m, const std::string& context);

/// Metadata that carries the part of a grid's scale OpenVDB's transform cannot hold: world
/// coordinates are this value times what the stored transform gives.
inline const char* const kWorldScaleMetadata = "pcvr_world_scale";

/// An OpenVDB transform for index_to_world, and the world scale it leaves out (1 when none).
/// OpenVDB refuses linear maps whose 3x3 determinant is below 3e-15 (voxels of about 1.4e-5 units);
/// such a matrix is stored divided by a power of ten that brings its voxels near one unit.
struct VdbTransform {
    openvdb::math::Transform::Ptr transform;
    double world_scale = 1.0;
};

/// Mat4 (column vectors: world = M [i j k 1]^T) <-> OpenVDB transform (row vectors: world = [i j k 1] A),
/// i.e. A = M^T. OpenVDB places voxel centres at integer index coordinates, as we do.
VdbTransform to_vdb_transform(const Mat4& m);
/// The grid's index_to_world, its kWorldScaleMetadata applied. Throws GridError (prefixed with
/// `context`) for frustum and other non-linear maps and for a bad scale.
Mat4 from_vdb_transform(const openvdb::GridBase& grid, const std::string& context);

/// Wrap a finished float grid: computes statistics; its transform becomes the Grid's index_to_world.
Grid make_grid(openvdb::FloatGrid::ConstPtr grid, const std::string& source_path, const std::string& name,
               const std::string& context);

}  // namespace detail
}  // namespace pcvr
