#include "shaded/albedo_field.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

/// The bounding box of a grid's blocks in block coordinates (index >> 3), inclusive; empty: i0 > i1.
std::array<int64_t, 6> block_box(const Grid& grid) {
    constexpr int64_t kHuge = std::numeric_limits<int64_t>::max();
    std::array<int64_t, 6> box{kHuge, kHuge, kHuge, -kHuge, -kHuge, -kHuge};
    for (const VoxelBlock& b : grid.blocks())
        for (int a = 0; a < 3; ++a) {
            box[a] = std::min(box[a], int64_t(b.origin[a]) >> 3);
            box[a + 3] = std::max(box[a + 3], int64_t(b.origin[a]) >> 3);
        }
    return box;
}

uint64_t block_key(int64_t bi, int64_t bj, int64_t bk) {
    return (uint64_t(bi) & 0x1fffff) << 42 | (uint64_t(bj) & 0x1fffff) << 21 | (uint64_t(bk) & 0x1fffff);
}

bool same_placement(const Mat4& a, const Mat4& b) {
    double scale = 0, difference = 0;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            scale = std::max(scale, std::abs(a.m[r][c]));
            difference = std::max(difference, std::abs(a.m[r][c] - b.m[r][c]));
        }
    return difference <= 1e-9 * std::max(scale, 1.0);
}

}  // namespace

AlbedoField::Voxels::Voxels(const Grid& grid, const std::array<int64_t, 6>& box) : background_(grid.background()), box_(box) {
    const bool empty = box[0] > box[3];
    const uint64_t count = empty ? 0 : uint64_t(box[3] - box[0] + 1) * uint64_t(box[4] - box[1] + 1) * uint64_t(box[5] - box[2] + 1);
    if (!empty && count <= kMostDenseBlocks) dense_.assign(count, nullptr);
    for (const VoxelBlock& b : grid.blocks()) {
        const int64_t bi = int64_t(b.origin[0]) >> 3, bj = int64_t(b.origin[1]) >> 3, bk = int64_t(b.origin[2]) >> 3;
        if (empty || bi < box[0] || bj < box[1] || bk < box[2] || bi > box[3] || bj > box[4] || bk > box[5]) continue;
        if (dense_.empty())
            hashed_.emplace(block_key(bi, bj, bk), &b);
        else
            dense_[(uint64_t(bi - box[0]) * uint64_t(box[4] - box[1] + 1) + uint64_t(bj - box[1])) * uint64_t(box[5] - box[2] + 1) +
                   uint64_t(bk - box[2])] = &b;
    }
}

const VoxelBlock* AlbedoField::Voxels::block(int64_t bi, int64_t bj, int64_t bk) const {
    if (bi < box_[0] || bj < box_[1] || bk < box_[2] || bi > box_[3] || bj > box_[4] || bk > box_[5]) return nullptr;
    if (!dense_.empty())
        return dense_[(uint64_t(bi - box_[0]) * uint64_t(box_[4] - box_[1] + 1) + uint64_t(bj - box_[1])) * uint64_t(box_[5] - box_[2] + 1) +
                      uint64_t(bk - box_[2])];
    const auto it = hashed_.find(block_key(bi, bj, bk));
    return it == hashed_.end() ? nullptr : it->second;
}

float AlbedoField::Voxels::value(int64_t i, int64_t j, int64_t k) const {
    const VoxelBlock* b = block(i >> 3, j >> 3, k >> 3);
    if (!b) return background_;
    const int offset = int(((i & 7) << 6) | ((j & 7) << 3) | (k & 7));
    return b->active(offset) ? b->value(offset) : background_;
}

void AlbedoField::add(double w, double d, const float colour[3], double sum[4]) {
    if (!(d > 0) || !std::isfinite(d) || !(w > 0)) return;
    for (int c = 0; c < 3; ++c)
        if (std::isfinite(colour[c])) sum[c] += w * d * double(colour[c]);
    sum[3] += w * d;
}

template <class Weight>
void AlbedoField::accumulate(const int64_t lo[3], const int64_t hi[3], Weight&& weight, double sum[4]) const {
    for (int64_t i = lo[0]; i <= hi[0]; ++i)
        for (int64_t j = lo[1]; j <= hi[1]; ++j)
            for (int64_t k = lo[2]; k <= hi[2]; ++k) {
                const double d = double(voxels_[0].value(i, j, k)) - density_background_;
                if (!(d > 0)) continue;
                const float colour[3] = {voxels_[1].value(i, j, k), voxels_[2].value(i, j, k), voxels_[3].value(i, j, k)};
                add(weight(i, j, k), d, colour, sum);
            }
}

Vec3f AlbedoField::mean_colour(const Grid& density) const {
    double sum[4] = {0, 0, 0, 0};
    for (const VoxelBlock& b : density.blocks()) {
        const int64_t bi = int64_t(b.origin[0]) >> 3, bj = int64_t(b.origin[1]) >> 3, bk = int64_t(b.origin[2]) >> 3;
        const VoxelBlock* colour_blocks[3] = {voxels_[1].block(bi, bj, bk), voxels_[2].block(bi, bj, bk), voxels_[3].block(bi, bj, bk)};
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            if (!b.active(offset)) continue;
            const float colour[3] = {voxels_[1].value(colour_blocks[0], offset), voxels_[2].value(colour_blocks[1], offset),
                                     voxels_[3].value(colour_blocks[2], offset)};
            add(1.0, double(b.value(offset)) - density_background_, colour, sum);
        }
    }
    if (!(sum[3] > 0)) return {1, 1, 1};
    return {float(sum[0] / sum[3]), float(sum[1] / sum[3]), float(sum[2] / sum[3])};
}

std::unique_ptr<AlbedoField> AlbedoField::of(const ShadedVolume& volume, const Vec3& origin) {
    const auto& colour = volume.albedo_grids;
    if (std::none_of(colour.begin(), colour.end(), [](const Grid* g) { return g != nullptr; })) return nullptr;
    return std::make_unique<AlbedoField>(*volume.grid, colour, origin);
}

AlbedoField::AlbedoField(const Grid& density, const std::array<const Grid*, 3>& colour, const Vec3& origin)
    : density_background_(density.background()) {
    static const char* kChannel[3] = {"red", "green", "blue"};
    for (int c = 0; c < 3; ++c) {
        if (!colour[c]) throw InvalidArgument("albedo_grids: the " + std::string(kChannel[c]) + " grid is missing (give all three)");
        if (!same_placement(colour[c]->index_to_world(), density.index_to_world()))
            throw InvalidArgument("albedo_grids: the " + std::string(kChannel[c]) + " grid '" + colour[c]->name() +
                                  "' does not lie on the voxels of grid '" + density.name() +
                                  "' (another index_to_world); albedo grids share their volume's voxels");
    }
    const std::optional<Mat4> to_index = density.index_to_world().inverse();
    if (!to_index) throw InvalidArgument("albedo_grids: grid '" + density.name() + "' has a singular index_to_world");
    Mat4 from_origin = Mat4::identity();
    from_origin.m[0][3] = origin.x, from_origin.m[1][3] = origin.y, from_origin.m[2][3] = origin.z;
    to_index_ = *to_index * from_origin;
    // Only voxels near density are weighted: the density grid's blocks bound every lookup that counts.
    const std::array<int64_t, 6> box = block_box(density);
    voxels_.emplace_back(density, box);
    for (const Grid* g : colour) voxels_.emplace_back(*g, box);
    // The whole volume's colour, for points beyond every voxel's reach that the post-filter's spread of a
    // sheet still gives a trace of density.
    mean_ = mean_colour(density);
}

Vec3f AlbedoField::at(const Vec3f& position) const {
    const Vec3 u = to_index_.transform_point({position.x, position.y, position.z});
    if (!(std::abs(u.x) < 1e15 && std::abs(u.y) < 1e15 && std::abs(u.z) < 1e15)) return mean_;
    const double x[3] = {u.x, u.y, u.z};
    int64_t base[3];
    double f[3];
    for (int a = 0; a < 3; ++a) base[a] = int64_t(std::floor(x[a])), f[a] = x[a] - double(base[a]);
    double sum[4] = {0, 0, 0, 0};
    const int64_t hi[3] = {base[0] + 1, base[1] + 1, base[2] + 1};
    accumulate(base, hi, [&](int64_t i, int64_t j, int64_t k) {
        return (i == base[0] ? 1 - f[0] : f[0]) * (j == base[1] ? 1 - f[1] : f[1]) * (k == base[2] ? 1 - f[2] : f[2]);
    }, sum);
    if (!(sum[3] > 0)) {
        // The kernel's fringe: the 4^3 voxels it reaches, nearer ones weighing more.
        const int64_t lo[3] = {base[0] - 1, base[1] - 1, base[2] - 1}, far[3] = {base[0] + 2, base[1] + 2, base[2] + 2};
        accumulate(lo, far, [&](int64_t i, int64_t j, int64_t k) {
            const double di = x[0] - double(i), dj = x[1] - double(j), dk = x[2] - double(k);
            return std::exp(-(di * di + dj * dj + dk * dk));
        }, sum);
    }
    if (!(sum[3] > 0)) return mean_;
    return {float(sum[0] / sum[3]), float(sum[1] / sum[3]), float(sum[2] / sum[3])};
}

Vec3x8 AlbedoField::at(const Vec3x8& position) const {
    Vec3x8 out;
    for (int l = 0; l < 8; ++l) {
        const Vec3f a = at(Vec3f{position.x[l], position.y[l], position.z[l]});
        out.x[l] = a.x, out.y[l] = a.y, out.z[l] = a.z;
    }
    return out;
}

}  // namespace pcvr
