#include "shaded/light/albedo_field.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "pcvr/errors.h"

namespace pcvr {

namespace {

/// The texels' share of their neighbours' colour where they have no density of their own.
constexpr float kBorrowed = 1e-3f;
/// Voxels the lattice reaches beyond the density's active box on each side: the kernel's reach.
constexpr int kMargin = 2;

uint64_t block_key(int64_t i, int64_t j, int64_t k) {
    return (uint64_t(i >> 3) & 0x1fffff) << 42 | (uint64_t(j >> 3) & 0x1fffff) << 21 | (uint64_t(k >> 3) & 0x1fffff);
}

/// A grid's blocks by their origin (block_key).
std::unordered_map<uint64_t, const VoxelBlock*> blocks_by_origin(const Grid& grid) {
    std::unordered_map<uint64_t, const VoxelBlock*> out;
    for (const VoxelBlock& b : grid.blocks()) out.emplace(block_key(b.origin[0], b.origin[1], b.origin[2]), &b);
    return out;
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

Mat4 translation(double x, double y, double z) {
    Mat4 m = Mat4::identity();
    m.m[0][3] = x, m.m[1][3] = y, m.m[2][3] = z;
    return m;
}

}  // namespace

std::unique_ptr<AlbedoField> AlbedoField::of(const ShadedVolume& volume, const Vec3& origin) {
    const auto& colour = volume.albedo_grids;
    if (std::none_of(colour.begin(), colour.end(), [](const Grid* g) { return g != nullptr; })) return nullptr;
    return std::make_unique<AlbedoField>(*volume.grid, colour, origin);
}

AlbedoField::AlbedoField(const Grid& density, const std::array<const Grid*, 3>& colour, const Vec3& origin) {
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
    if (density.blocks().empty()) return;  // no density: the factor is 1 everywhere

    // The density's active box widened by the kernel's reach, a texel per voxel where that fits.
    const std::array<int32_t, 6> box = density.index_bbox();
    std::array<double, 3> low, extent;
    double count = 1;
    for (int a = 0; a < 3; ++a) {
        low[a] = double(box[a]) - kMargin;
        extent[a] = double(box[a + 3]) - double(box[a]) + 2 * kMargin;
        count *= extent[a] + 1;
    }
    double spacing = std::max(1.0, std::cbrt(count / double(kMostTexels)));
    for (;; spacing *= 1.01) {
        for (int a = 0; a < 3; ++a) n_[a] = int64_t(std::ceil(extent[a] / spacing)) + 1;
        if (uint64_t(n_[0]) * uint64_t(n_[1]) * uint64_t(n_[2]) <= kMostTexels) break;
    }
    const Mat4 scale = Mat4::from_rows({1 / spacing, 0, 0, 0, 0, 1 / spacing, 0, 0, 0, 0, 1 / spacing, 0, 0, 0, 0, 1});
    to_lattice_ = scale * translation(-low[0], -low[1], -low[2]) * *to_index * translation(origin.x, origin.y, origin.z);
    texels_.assign(size_t(n_[0] * n_[1] * n_[2]) * kChannels, 0.0f);

    const std::array<double, kChannels> whole = fill(density, colour, low, spacing);
    if (whole[3] > 0) mean_ = {float(whole[0] / whole[3]), float(whole[1] / whole[3]), float(whole[2] / whole[3])};
    dilate();
}

std::array<double, AlbedoField::kChannels> AlbedoField::fill(const Grid& density, const std::array<const Grid*, 3>& colour,
                                                            const std::array<double, 3>& low, double spacing) {
    std::array<std::unordered_map<uint64_t, const VoxelBlock*>, 3> colour_blocks;
    for (int c = 0; c < 3; ++c) colour_blocks[c] = blocks_by_origin(*colour[c]);
    const float background = density.background();
    std::array<double, kChannels> whole{0, 0, 0, 0};
    for (const VoxelBlock& b : density.blocks()) {
        const VoxelBlock* parts[3];
        for (int c = 0; c < 3; ++c) {
            const auto it = colour_blocks[c].find(block_key(b.origin[0], b.origin[1], b.origin[2]));
            parts[c] = it == colour_blocks[c].end() ? nullptr : it->second;
        }
        for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
            const double d = b.active(offset) ? double(b.value(offset)) - background : 0.0;
            if (!(d > 0) || !std::isfinite(d)) continue;
            float rgb[3];
            for (int c = 0; c < 3; ++c) {
                const float v = parts[c] && parts[c]->active(offset) ? parts[c]->value(offset) : colour[c]->background();
                rgb[c] = std::isfinite(v) ? v : 0.0f;
            }
            const int64_t voxel[3] = {b.origin[0] + (offset >> 6), b.origin[1] + ((offset >> 3) & 7), b.origin[2] + (offset & 7)};
            int64_t t[3];
            for (int a = 0; a < 3; ++a) t[a] = std::clamp(int64_t(std::lround((double(voxel[a]) - low[a]) / spacing)), int64_t(0), n_[a] - 1);
            float* texel = texels_.data() + kChannels * index(t[0], t[1], t[2]);
            for (int c = 0; c < 3; ++c) texel[c] += float(d) * rgb[c];
            texel[3] += float(d);
            whole[0] += d * rgb[0], whole[1] += d * rgb[1], whole[2] += d * rgb[2], whole[3] += d;
        }
    }
    return whole;
}

void AlbedoField::dilate() {
    // Tent weights over 5^3 texels: a box of three along each axis, twice.
    std::vector<float> sums = texels_;
    std::vector<float> line;
    const size_t stride[3] = {size_t(n_[1] * n_[2]), size_t(n_[2]), 1};
    for (int pass = 0; pass < 6; ++pass) {
        const int a = pass % 3, p = (a + 1) % 3, q = (a + 2) % 3;  // along axis a, line by line over p and q
        line.resize(size_t(n_[a]) * kChannels);
        for (int64_t u = 0; u < n_[p]; ++u)
            for (int64_t v = 0; v < n_[q]; ++v) {
                const size_t start = size_t(u) * stride[p] + size_t(v) * stride[q];
                for (int64_t x = 0; x < n_[a]; ++x)
                    std::copy_n(sums.data() + kChannels * (start + size_t(x) * stride[a]), kChannels, line.data() + kChannels * x);
                for (int64_t x = 0; x < n_[a]; ++x) {
                    float* s = sums.data() + kChannels * (start + size_t(x) * stride[a]);
                    for (int c = 0; c < kChannels; ++c)
                        s[c] = line[kChannels * x + c] + (x > 0 ? line[kChannels * (x - 1) + c] : 0.0f) +
                               (x + 1 < n_[a] ? line[kChannels * (x + 1) + c] : 0.0f);
                }
            }
    }
    for (size_t i = 0; i < texels_.size(); i += kChannels)
        if (!(texels_[i + 3] > 0))
            for (int c = 0; c < kChannels; ++c) texels_[i + c] = kBorrowed * sums[i + c];
}

Vec3f AlbedoField::at(const Vec3f& position) const {
    const Vec3x8 lanes = at(Vec3x8{broadcast8(position.x), broadcast8(position.y), broadcast8(position.z)});
    return {lanes.x[0], lanes.y[0], lanes.z[0]};
}

Vec3x8 AlbedoField::at(const Vec3x8& position) const {
    const Vec3x8 mean{broadcast8(mean_.x), broadcast8(mean_.y), broadcast8(mean_.z)};
    if (texels_.empty()) return mean;
    // Lattice coordinates in float: positions relative to the origin (the camera) are small.
    const auto& m = to_lattice_.m;
    float8 u[3], f[3];
    int8x base[3], inside = int8x{} - 1;
    for (int a = 0; a < 3; ++a) {
        u[a] = float(m[a][0]) * position.x + float(m[a][1]) * position.y + float(m[a][2]) * position.z + float(m[a][3]);
        inside &= (u[a] >= 0.0f) & (u[a] <= float(n_[a] - 1));
        const float8 clamped = clamp8(u[a], 0.0f, float(n_[a] - 2));  // NaN: 0 (then outside)
        base[a] = __builtin_convertvector(clamped, int8x);
        f[a] = clamp8(u[a] - __builtin_convertvector(base[a], float8), 0.0f, 1.0f);
    }
    const int32_t stride[3] = {int32_t(n_[1] * n_[2]), int32_t(n_[2]), 1};
    const int8x first = base[0] * stride[0] + base[1] * stride[1] + base[2];
    const float* channels = texels_.data();
    float8 sum[kChannels] = {};
    for (int corner = 0; corner < 8; ++corner) {
        const int dx = corner >> 2, dy = (corner >> 1) & 1, dz = corner & 1;
        const float8 w = (dx ? f[0] : 1.0f - f[0]) * (dy ? f[1] : 1.0f - f[1]) * (dz ? f[2] : 1.0f - f[2]);
        const int8x at = kChannels * (first + (dx * stride[0] + dy * stride[1] + dz));
        for (int c = 0; c < kChannels; ++c) sum[c] += w * gather8(channels + c, at);
    }
    const int8x found = inside & (sum[3] > 0.0f);
    const float8 weight = select8(found, sum[3], broadcast8(1.0f));
    return {select8(found, sum[0] / weight, mean.x), select8(found, sum[1] / weight, mean.y), select8(found, sum[2] / weight, mean.z)};
}

}  // namespace pcvr
