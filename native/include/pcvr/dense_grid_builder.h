/// @file dense_grid_builder.h
/// @brief Builds a Grid from a dense volume delivered a slab of i-planes at a time.
///
/// A converter that reads a scan slice by slice (a DICOM series, a compressed NIfTI) hands each slab
/// over and drops it: the build holds the sparse grid and one slab, never the whole dense array.
/// Grid::from_dense is this builder fed one slab. Not thread-safe: one builder per thread.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <string>

#include "pcvr/grid.h"
#include "pcvr/math.h"

namespace pcvr {

class DenseGridBuilder {
public:
    /// A grid of `shape` voxels indexed [i][j][k], placed by `index_to_world`; voxels equal to
    /// `background` stay inactive. Throws GridError on a bad transform, background or shape; errors
    /// start with `caller` and the grid's name.
    DenseGridBuilder(std::array<size_t, 3> shape, const Mat4& index_to_world, float background,
                     const std::string& name = "density", const std::string& caller = "Grid.from_dense");
    ~DenseGridBuilder();
    DenseGridBuilder(const DenseGridBuilder&) = delete;
    DenseGridBuilder& operator=(const DenseGridBuilder&) = delete;

    /// Copy the next `count` i-planes, `values` in C order [count][shape[1]][shape[2]]. Throws
    /// GridError on NaN or infinity (naming the voxel) or on more planes than the shape holds.
    void add_planes(const float* values, size_t count);
    size_t planes_added() const;
    /// The grid; throws GridError unless all shape[0] planes were added. The builder is spent.
    Grid finish();

private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace pcvr
