#include "view/brick_order.h"

#include <algorithm>
#include <map>
#include <numeric>

namespace pcvr {

namespace {

int64_t floor_div(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/// Per cell (of `side` voxels along each axis), the bytes of the boxes that meet the cell grown by `margin`:
/// a leaf's whole, a larger box's (a tile's) voxels within it.
std::map<std::array<int64_t, 3>, uint64_t> bytes_per_cell(const std::vector<std::array<int32_t, 6>>& boxes, const BrickSides& side,
                                                          int margin) {
    std::map<std::array<int64_t, 3>, uint64_t> bytes;
    for (const auto& b : boxes) {
        // The cells whose grown box meets b: those whose own cells meet b grown by the margin.
        std::array<int64_t, 3> first, last;
        for (int a = 0; a < 3; ++a) {
            first[a] = floor_div(int64_t(b[a]) - margin, side[a]);
            last[a] = floor_div(int64_t(b[a + 3]) + margin, side[a]);
        }
        const bool leaf = b[3] - b[0] < 8;
        for (int64_t i = first[0]; i <= last[0]; ++i)
            for (int64_t j = first[1]; j <= last[1]; ++j)
                for (int64_t k = first[2]; k <= last[2]; ++k) {
                    uint64_t voxels = 1;
                    const int64_t cell[3] = {i, j, k};
                    for (int a = 0; a < 3; ++a) {
                        const int64_t lo = std::max<int64_t>(b[a], cell[a] * side[a] - margin);
                        const int64_t hi = std::min<int64_t>(b[a + 3], (cell[a] + 1) * side[a] - 1 + margin);
                        voxels *= uint64_t(leaf ? b[a + 3] - b[a] + 1 : hi - lo + 1);
                    }
                    bytes[{i, j, k}] += voxels * sizeof(float);
                }
    }
    return bytes;
}

}  // namespace

std::vector<Brick> cut_into_bricks(const std::vector<std::array<int32_t, 6>>& value_boxes, const BrickSides& side, int margin) {
    const auto bytes = bytes_per_cell(value_boxes, side, margin);
    if (bytes.empty()) return {};
    // The cells of the values themselves bound the partition: beyond them bricks stay open.
    std::array<int64_t, 3> least{INT64_MAX, INT64_MAX, INT64_MAX}, most{INT64_MIN, INT64_MIN, INT64_MIN};
    for (const auto& b : value_boxes)
        for (int a = 0; a < 3; ++a) {
            least[a] = std::min(least[a], floor_div(b[a], side[a]));
            most[a] = std::max(most[a], floor_div(b[a + 3], side[a]));
        }
    std::vector<Brick> bricks;
    for (const auto& [cell, cell_bytes] : bytes) {
        bool inside = true;
        for (int a = 0; a < 3; ++a) inside = inside && cell[a] >= least[a] && cell[a] <= most[a];
        if (!inside) continue;  // a cell that only the margin of the values reaches
        Brick brick;
        brick.cell = cell;
        brick.bytes = cell_bytes;
        for (int a = 0; a < 3; ++a) {
            const int64_t first = cell[a] * side[a], last = first + side[a] - 1;
            // The outer bricks read and own what lies beyond the partition too.
            brick.read_box[a] = int32_t(std::max<int64_t>(INT32_MIN, cell[a] == least[a] ? INT32_MIN : first - margin));
            brick.read_box[a + 3] = int32_t(std::min<int64_t>(INT32_MAX, cell[a] == most[a] ? INT32_MAX : last + margin));
            // Voxel centres sit at whole index coordinates: the box owns first .. last and half a voxel each way.
            brick.owned.lo[a] = cell[a] == least[a] ? -INFINITY : double(first) - 0.5;
            brick.owned.hi[a] = cell[a] == most[a] ? INFINITY : double(last) + 0.5;
        }
        bricks.push_back(brick);
    }
    return bricks;
}

BrickSides brick_sides(const std::vector<std::array<int32_t, 6>>& value_boxes, int margin,
                       const std::function<bool(const BrickSides& sides, uint64_t bytes)>& fits) {
    uint64_t cells = 0;
    auto all_fit = [&](const BrickSides& sides) {
        const auto bytes = bytes_per_cell(value_boxes, sides, margin);
        uint64_t largest = 0;
        for (const auto& [cell, b] : bytes) largest = std::max(largest, b);
        cells = bytes.size();
        return fits(sides, largest);
    };
    // Cubes first: the largest power-of-two side that fits.
    BrickSides best{0, 0, 0};
    for (int side = 16; side <= 4096; side *= 2) {
        if (!all_fit({side, side, side})) break;
        best = {side, side, side};
        if (cells <= 1) return best;  // one brick holds it all
    }
    if (best[0] == 0) return best;
    // Then each axis, the longest of the values' extent first, as long as still fits, in steps of 16 voxels
    // (whole leaves; bricks of 128 x 128 x 96 read 20% fewer leaves than cubes of 64 with their margins).
    std::array<int64_t, 3> extent{0, 0, 0};
    std::array<int64_t, 3> lo{INT64_MAX, INT64_MAX, INT64_MAX}, hi{INT64_MIN, INT64_MIN, INT64_MIN};
    for (const auto& b : value_boxes)
        for (int a = 0; a < 3; ++a) lo[a] = std::min<int64_t>(lo[a], b[a]), hi[a] = std::max<int64_t>(hi[a], b[a + 3]);
    for (int a = 0; a < 3; ++a) extent[a] = hi[a] - lo[a] + 1;
    std::array<int, 3> axes{0, 1, 2};
    std::stable_sort(axes.begin(), axes.end(), [&](int x, int y) { return extent[x] > extent[y]; });
    for (int a : axes) {
        // The largest multiple of 16 up to twice the cube's side that fits (bisection: larger bricks read more).
        int fitting = best[a], failing = 2 * best[a];
        while (failing - fitting > 16) {
            BrickSides trial = best;
            trial[a] = (fitting + failing) / 2 / 16 * 16;
            if (all_fit(trial)) fitting = trial[a];
            else failing = trial[a];
        }
        best[a] = fitting;
    }
    return best;
}

std::vector<size_t> visibility_order(const std::vector<Brick>& bricks, const BrickSides& side, const Camera& camera,
                                     const Mat4& index_to_world) {
    const Mat4 to_index = *index_to_world.inverse();
    const Mat4 camera_to_index = to_index * camera.camera_to_world();
    std::vector<int64_t> key(bricks.size());
    if (camera.orthographic()) {
        // Along the rays the cells count up where the view direction's index component is positive.
        const Vec3 ahead = camera_to_index.transform_vector({0, 0, -1});
        for (size_t b = 0; b < bricks.size(); ++b)
            for (int a = 0; a < 3; ++a) key[b] += ahead[a] > 0 ? bricks[b].cell[a] : ahead[a] < 0 ? -bricks[b].cell[a] : 0;
    } else {
        // The eye's cell, clamped to the partition as its outer bricks are open outwards.
        const Vec3 eye = camera_to_index.transform_point(camera.eye());
        std::array<int64_t, 3> least{INT64_MAX, INT64_MAX, INT64_MAX}, most{INT64_MIN, INT64_MIN, INT64_MIN};
        for (const Brick& brick : bricks)
            for (int a = 0; a < 3; ++a) least[a] = std::min(least[a], brick.cell[a]), most[a] = std::max(most[a], brick.cell[a]);
        for (int a = 0; a < 3; ++a) {
            const double cell = std::floor((eye[a] + 0.5) / side[a]);
            const int64_t at = cell < double(least[a]) ? least[a] : cell > double(most[a]) ? most[a] : int64_t(cell);
            for (size_t b = 0; b < bricks.size(); ++b) key[b] += std::abs(bricks[b].cell[a] - at);
        }
    }
    std::vector<size_t> order(bricks.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) { return key[x] < key[y]; });
    return order;
}

}  // namespace pcvr
