#include "splat/splat_grid.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

namespace pcvr {

namespace {
// The same floor as PostFilterAxis::node of the last pixel.
int nodes_across(int pixels, double stride, int margin) { return int(std::floor((pixels - 1) / stride)) + 1 + 2 * margin; }
}  // namespace

SplatGrid::SplatGrid(int width, int height, double stride, int margin) : stride_(stride) {
    node_x0_ = -margin;
    node_y0_ = -margin;
    nx_ = nodes_across(width, stride, margin);
    ny_ = nodes_across(height, stride, margin);
    tiles_x_ = (nx_ + kTile - 1) / kTile;
    tiles_y_ = (ny_ + kTile - 1) / kTile;
    values_ = ZeroedBuffer<double>(size_t(nx_) * ny_ + kPadding);
    touched_.assign(size_t(tiles_x_) * tiles_y_, 0);
}

uint64_t SplatGrid::bytes(int width, int height, double stride, int margin) {
    const uint64_t nx = uint64_t(nodes_across(width, stride, margin)), ny = uint64_t(nodes_across(height, stride, margin));
    const uint64_t tiles = ((nx + kTile - 1) / kTile) * ((ny + kTile - 1) / kTile);
    return (nx * ny + kPadding) * sizeof(double) + tiles;
}

SplatGrid SplatGrid::zero_like() const {
    SplatGrid out;
    out.stride_ = stride_;
    out.node_x0_ = node_x0_;
    out.node_y0_ = node_y0_;
    out.nx_ = nx_;
    out.ny_ = ny_;
    out.tiles_x_ = tiles_x_;
    out.tiles_y_ = tiles_y_;
    out.values_ = ZeroedBuffer<double>(values_.size());
    out.touched_.assign(touched_.size(), 0);
    return out;
}

void SplatGrid::mark(int c0, int r0, int c1, int r1) {
    c0 = std::max(c0, 0);
    r0 = std::max(r0, 0);
    c1 = std::min(c1, nx_ - 1);
    r1 = std::min(r1, ny_ - 1);
    if (c0 > c1 || r0 > r1) return;
    for (int ty = r0 / kTile; ty <= r1 / kTile; ++ty)
        for (int tx = c0 / kTile; tx <= c1 / kTile; ++tx) touched_[size_t(ty) * tiles_x_ + tx] = 1;
}

void SplatGrid::add(const SplatGrid& other) {
    // Tile rows in parallel (a stride-1 grid is a whole image); only touched tiles can hold values.
    tbb::parallel_for(0, tiles_y_, [&](int ty) {
        for (int tx = 0; tx < tiles_x_; ++tx) {
            const size_t t = size_t(ty) * tiles_x_ + tx;
            if (!other.touched_[t]) continue;
            touched_[t] = 1;
            const int c0 = tx * kTile, c1 = std::min(c0 + kTile, nx_);
            for (int r = ty * kTile; r < std::min((ty + 1) * kTile, ny_); ++r) {
                double* dst = row(r);
                const double* src = other.row(r);
                for (int c = c0; c < c1; ++c) dst[c] += src[c];
            }
        }
    });
}

}  // namespace pcvr
