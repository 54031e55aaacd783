/// @file sheet_buffer.h
/// @brief A tile's sheet buffer: the ring of sheets that one grid's slabs are still landing in.
///
/// Voxels are splatted front to back, each into the few sheets its kernel reaches, a little ahead of
/// the sheet being composited: only `depth` sheets are ever alive, however deep the volume (the paper's
/// reference [6] keeps a whole-volume stack; a ring is all the walk needs). Sheet s lives in slot
/// s mod depth; the walk releases a sheet when it is done with it, which zeroes its slot for sheet
/// s + depth. Sheets are at the grid's subgrid resolution (one value per node), in float: a node
/// takes contributions from a few dozen voxels per sheet at most. Rows have 8 floats of padding so
/// that deposits may write whole vectors. One ring per grid per worker thread, reused tile after tile.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace pcvr {

class SheetRing {
public:
    static constexpr int kRowPadding = 8;

    /// `columns` x `rows` nodes per sheet, `depth` sheets, all zero.
    void reset(int columns, int rows, int depth) {
        columns_ = columns;
        rows_ = rows;
        pitch_ = size_t(columns) + kRowPadding;
        depth_ = depth;
        sheet_size_ = pitch_ * size_t(rows);
        values_.assign(sheet_size_ * depth + kRowPadding, 0.0f);
        touched_.assign(depth, 0);
    }

    int columns() const { return columns_; }
    int rows() const { return rows_; }
    size_t pitch() const { return pitch_; }
    int depth() const { return depth_; }

    float* sheet(int64_t s) { return values_.data() + slot(s) * sheet_size_; }
    const float* sheet(int64_t s) const { return values_.data() + slot(s) * sheet_size_; }
    bool touched(int64_t s) const { return touched_[slot(s)] != 0; }
    void touch(int64_t s) { touched_[slot(s)] = 1; }

    /// Done with sheet s: its slot is zeroed for sheet s + depth.
    void release(int64_t s) {
        const size_t k = slot(s);
        if (!touched_[k]) return;
        std::fill_n(values_.data() + k * sheet_size_, sheet_size_, 0.0f);
        touched_[k] = 0;
    }
    /// Every sheet released.
    void clear() {
        for (int k = 0; k < depth_; ++k) release(k);
    }

private:
    size_t slot(int64_t s) const { return size_t(((s % depth_) + depth_) % depth_); }

    int columns_ = 0, rows_ = 0, depth_ = 1;
    size_t pitch_ = 0, sheet_size_ = 0;
    std::vector<float> values_;
    std::vector<uint8_t> touched_;
};

}  // namespace pcvr
