/// @file sheet_buffer.h
/// @brief A tile's sheet buffer: the ring of sheets that one grid's slabs are still landing in.
///
/// Voxels are splatted front to back, each into the few sheets its kernel reaches, a little ahead of
/// the sheet being composited: only `depth` sheets are ever alive, however deep the volume (the paper's
/// reference [6] keeps a whole-volume stack; a ring is all the walk needs). Sheet s lives in slot
/// s mod depth (a power of two, so that the slot is a mask); the walk releases a sheet when it is
/// done with it, which zeroes its slot for sheet s + depth. Sheets are at the grid's subgrid resolution (one value per node), in float: a node
/// takes contributions from a few dozen voxels per sheet at most. Rows have 8 floats of padding so
/// that deposits may write whole vectors. One ring per grid per worker thread, reused tile after tile.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace pcvr {

/// An inclusive rectangle of nodes or pixels; empty when x0 > x1.
struct Box {
    int x0 = 1, y0 = 1, x1 = 0, y1 = 0;
    bool empty() const { return x0 > x1 || y0 > y1; }
    void include(const Box& b) {
        if (b.empty()) return;
        if (empty()) {
            *this = b;
            return;
        }
        x0 = std::min(x0, b.x0), y0 = std::min(y0, b.y0), x1 = std::max(x1, b.x1), y1 = std::max(y1, b.y1);
    }
    Box grown(int by) const { return empty() ? *this : Box{x0 - by, y0 - by, x1 + by, y1 + by}; }
    Box clipped(const Box& to) const {
        const Box b{std::max(x0, to.x0), std::max(y0, to.y0), std::min(x1, to.x1), std::min(y1, to.y1)};
        return b.empty() ? Box{} : b;
    }
};

class SheetRing {
public:
    static constexpr int kRowPadding = 8;

    /// `columns` x `rows` nodes per sheet, at least `sheets` sheets, all zero.
    void reset(int columns, int rows, int sheets) {
        columns_ = columns;
        rows_ = rows;
        pitch_ = size_t(columns) + kRowPadding;
        depth_ = 1;
        while (depth_ < sheets) depth_ *= 2;
        sheet_size_ = pitch_ * size_t(rows);
        values_.assign(sheet_size_ * depth_ + kRowPadding, 0.0f);
        touched_.assign(depth_, Box{});
    }

    int columns() const { return columns_; }
    int rows() const { return rows_; }
    size_t pitch() const { return pitch_; }
    int depth() const { return depth_; }

    float* sheet(int64_t s) { return values_.data() + slot(s) * sheet_size_; }
    const float* sheet(int64_t s) const { return values_.data() + slot(s) * sheet_size_; }
    /// The nodes splats reached in sheet s (zero outside it); empty when none did.
    const Box& touched(int64_t s) const { return touched_[slot(s)]; }
    void touch(int64_t s, const Box& nodes) { touched_[slot(s)].include(nodes); }

    /// Done with sheet s: its slot is zeroed for sheet s + depth. Only what splats reached needs it
    /// (a deposit's vectors may run 7 nodes past its window with zero weights, which leave zeros).
    void release(int64_t s) {
        const size_t k = slot(s);
        const Box b = touched_[k];
        if (b.empty()) return;
        for (int r = b.y0; r <= b.y1; ++r)
            std::fill_n(values_.data() + k * sheet_size_ + size_t(r) * pitch_ + b.x0, b.x1 - b.x0 + 1, 0.0f);
        touched_[k] = Box{};
    }

private:
    size_t slot(int64_t s) const { return size_t(s & (depth_ - 1)); }  // two's complement: right for s < 0 too

    int columns_ = 0, rows_ = 0, depth_ = 1;
    size_t pitch_ = 0, sheet_size_ = 0;
    std::vector<float> values_;
    std::vector<Box> touched_;
};

}  // namespace pcvr
