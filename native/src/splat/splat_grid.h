/// @file splat_grid.h
/// @brief The accumulation buffer splats land in: a node every `stride` image pixels, plus a margin.
///
/// Node (i, j) sits on image pixel (stride * i, stride * j), so for stride 1 the grid is the image
/// itself and for stride L it is PCVR's subgrid, stored compactly (the paper's "adjusting indices").
/// The stride need not be whole: X-ray subgrids put one node per projected voxel spacing.
/// Nodes extend `margin` beyond the image on each side because the post-convolution reads them.
/// Values are double: thousands of voxels can land on one node without losing precision.
/// Tiles of kTile x kTile nodes remember whether anything landed in them, so the post-convolution
/// can skip empty space. A SplatGrid is not thread-safe: each worker splats into its own and the
/// results are added with `add()`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "pcvr/zeroed_buffer.h"

namespace pcvr {

class SplatGrid {
public:
    static constexpr int kTile = 16;
    /// Extra doubles after the last row, so vector loops may run up to 7 entries past a row's end.
    static constexpr int kPadding = 8;

    SplatGrid() = default;
    /// The grid of nodes `stride` >= 1 pixels apart covering a width x height image with `margin`
    /// extra nodes per side.
    SplatGrid(int width, int height, double stride, int margin);
    /// What such a grid allocates (for MemoryBudget).
    static uint64_t bytes(int width, int height, double stride, int margin);

    double stride() const { return stride_; }
    int first_node_x() const { return node_x0_; }  ///< node index of column 0 (negative: margin)
    int first_node_y() const { return node_y0_; }
    int columns() const { return nx_; }
    /// Storage node coordinates of pixel coordinates (T: double, or a vector of doubles).
    template <class T>
    T node_x(T px) const { return px / stride_ - double(node_x0_); }
    template <class T>
    T node_y(T py) const { return py / stride_ - double(node_y0_); }
    int rows() const { return ny_; }

    double* row(int r) { return values_.data() + size_t(r) * nx_; }
    const double* row(int r) const { return values_.data() + size_t(r) * nx_; }

    /// Mark the tiles overlapping columns [c0, c1] x rows [r0, r1] (storage indices, clamped) as touched.
    void mark(int c0, int r0, int c1, int r1);
    bool tile_touched(int tile_column, int tile_row) const { return touched_[size_t(tile_row) * tiles_x_ + tile_column] != 0; }
    int tiles_x() const { return tiles_x_; }
    int tiles_y() const { return tiles_y_; }

    /// A grid of the same shape holding zeros (for a worker's private accumulation).
    SplatGrid zero_like() const;
    /// this += other (same shape), tile flags included.
    void add(const SplatGrid& other);

private:
    double stride_ = 1;
    int node_x0_ = 0, node_y0_ = 0, nx_ = 0, ny_ = 0, tiles_x_ = 0, tiles_y_ = 0;
    ZeroedBuffer<double> values_;
    std::vector<uint8_t> touched_;
};

}  // namespace pcvr
