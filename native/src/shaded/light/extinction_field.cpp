#include "shaded/light/extinction_field.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "pcvr/errors.h"
#include "pcvr/transfer_function.h"
#include "pcvr/zeroed_buffer.h"
#include "shaded/classify/shaded_levels.h"

namespace pcvr {

/// One grid resampled: departures from the background at its voxel centres, [i][j][k] with k fastest.
struct ExtinctionField::Lattice {
    static constexpr int kBrick = 4;  // voxels per brick side of the occupancy map
    int n[3] = {0, 0, 0};
    ZeroedBuffer<float> departure;
    /// Per brick of kBrick^3 voxels: 1 where a point whose trilinear cell lies in it (voxels kBrick b to
    /// kBrick b + kBrick) may have extinction, else 0. Most of a CT's box is air or, under a bone-like transfer
    /// function, transparent tissue: points there cost one lookup instead of eight.
    int bricks[3] = {0, 0, 0};
    std::vector<float> occupied;
    float to_lattice[3][4];  // relative position -> lattice coordinates
    float scale = 1, offset = 0;  // density = departure * scale + offset
    std::unique_ptr<ClassificationTable> table;
    std::optional<SampleClip> clip;

    size_t index(int i, int j, int k) const { return (size_t(i) * n[1] + j) * n[2] + k; }

    void map_occupancy() {
        for (int a = 0; a < 3; ++a) bricks[a] = (n[a] - 1 + kBrick - 1) / kBrick;
        const size_t count = size_t(bricks[0]) * bricks[1] * bricks[2];
        auto brick_index = [&](int bi, int bj, int bk) { return (size_t(bi) * bricks[1] + bj) * bricks[2] + bk; };
        // The range of each brick's own voxels (kBrick b to kBrick b + kBrick - 1), each voxel read once...
        std::vector<float> lo(count, INFINITY), hi(count, -INFINITY);
        // (the last brick along each axis also takes the voxels beyond it: n - 1 may be a multiple of kBrick).
        auto end = [&](int a, int b) { return b == bricks[a] - 1 ? n[a] : (b + 1) * kBrick; };
        tbb::parallel_for(0, bricks[0], [&](int bi) {
            for (int i = bi * kBrick; i < end(0, bi); ++i)
                for (int j = 0; j < n[1]; ++j) {
                    const float* row = departure.data() + index(i, j, 0);
                    const size_t first = brick_index(bi, std::min(j / kBrick, bricks[1] - 1), 0);
                    for (int bk = 0; bk < bricks[2]; ++bk) {
                        float a = lo[first + bk], b = hi[first + bk];
                        for (int k = bk * kBrick; k < end(2, bk); ++k) a = std::min(a, row[k]), b = std::max(b, row[k]);
                        lo[first + bk] = a, hi[first + bk] = b;
                    }
                }
        });
        // ...and with the next brick's along each axis, the cells that reach voxel kBrick b + kBrick.
        occupied.assign(count, 0.0f);
        tbb::parallel_for(0, bricks[0], [&](int bi) {
            for (int bj = 0; bj < bricks[1]; ++bj)
                for (int bk = 0; bk < bricks[2]; ++bk) {
                    float a = INFINITY, b = -INFINITY;
                    for (int di = 0; di <= std::min(1, bricks[0] - 1 - bi); ++di)
                        for (int dj = 0; dj <= std::min(1, bricks[1] - 1 - bj); ++dj)
                            for (int dk = 0; dk <= std::min(1, bricks[2] - 1 - bk); ++dk) {
                                const size_t at = brick_index(bi + di, bj + dj, bk + dk);
                                a = std::min(a, lo[at]), b = std::max(b, hi[at]);
                            }
                    // Trilinear values lie between the corners'; 0 itself is empty (no voxel reaches).
                    const double from = double(a) * scale + offset, to = double(b) * scale + offset;
                    const bool clear = (a == 0 && b == 0) || table->transparent(std::min(from, to), std::max(from, to));
                    occupied[brick_index(bi, bj, bk)] = clear ? 0.0f : 1.0f;
                }
        });
    }
};

namespace {

/// The kernel's weights at whole offsets -m..m along one axis (the offsets within its radius lie in that
/// cube), such that the weight at offset o is w0 u(ox) u(oy) u(oz): true of the Gaussians (products of
/// their axes' factors, truncated beyond the cube) and of the kernels that reach only the centre.
std::vector<float> axis_weights(const Kernel& kernel, int m, double& w0) {
    const double R = kernel.radius();
    auto weight = [&](double x, double y, double z) {
        const double r = std::sqrt(x * x + y * y + z * z);
        return r < R ? kernel.value(r) : 0.0;
    };
    w0 = weight(0, 0, 0);
    std::vector<float> u(2 * m + 1);
    for (int o = -m; o <= m; ++o) u[o + m] = float(weight(o, 0, 0) / w0);
    for (int x = -m; x <= m; ++x)
        for (int y = -m; y <= m; ++y)
            for (int z = -m; z <= m; ++z)
                if (std::abs(weight(x, y, z) - w0 * u[x + m] * u[y + m] * u[z + m]) > 1e-6 * w0)
                    throw Error(std::string("shadows: kernel '") + kernel.name() + "' is not separable at whole offsets");
    return u;
}

/// `values += w * from` over `count` floats, offset o of the weights u (-m..m): the inner loop of the convolution.
void add_weighted(float* to, const float* from, size_t count, float w) {
    for (size_t e = 0; e < count; ++e) to[e] += w * from[e];
}

/// Convolves the [i][j][k] lattice `values` with u(oi) u(oj) u(ok), zero beyond its ends, into `out` (then
/// swapped in). One sweep over i in chunks: each chunk convolves the slabs it reads along j and k in a buffer
/// of its own (a slab fits in the cache), then sums them along i, so memory is read and written once.
void convolve(ZeroedBuffer<float>& values, ZeroedBuffer<float>& out, const int (&n)[3], const std::vector<float>& u, int m) {
    if (m == 0) return;
    constexpr int kChunk = 16;
    const size_t slab = size_t(n[1]) * n[2];
    if (out.size() != values.size()) out = ZeroedBuffer<float>(values.size());  // every value is written below
    tbb::parallel_for(0, (n[0] + kChunk - 1) / kChunk, [&](int chunk) {
        const int i0 = chunk * kChunk, i1 = std::min(n[0], i0 + kChunk);
        const int first = std::max(0, i0 - m), last = std::min(n[0], i1 + m);
        std::vector<float> planes(size_t(last - first) * slab), line(n[2]);
        for (int i = first; i < last; ++i) {
            float* plane = planes.data() + size_t(i - first) * slab;
            const float* in = values.data() + size_t(i) * slab;
            for (int j = 0; j < n[1]; ++j) {
                float* row = plane + size_t(j) * n[2];
                for (int o = std::max(-m, -j); o <= std::min(m, n[1] - 1 - j); ++o) add_weighted(row, in + size_t(j + o) * n[2], n[2], u[o + m]);
                std::copy_n(row, n[2], line.data());
                std::fill_n(row, n[2], 0.0f);
                for (int o = -m; o <= m; ++o) {
                    const int from = std::max(0, -o), to = std::min(n[2], n[2] - o);
                    if (from < to) add_weighted(row + from, line.data() + from + o, size_t(to - from), u[o + m]);
                }
            }
        }
        for (int i = i0; i < i1; ++i) {
            float* to = out.data() + size_t(i) * slab;
            std::fill_n(to, slab, 0.0f);
            for (int o = std::max(-m, -i); o <= std::min(m, n[0] - 1 - i); ++o)
                add_weighted(to, planes.data() + size_t(i + o - first) * slab, slab, u[o + m]);
        }
    });
    std::swap(values, out);
}

}  // namespace

ExtinctionField::ExtinctionField(const std::vector<ShadedVolume>& volumes, const Kernel& kernel, const Vec3& origin) {
    const int m = int(std::ceil(kernel.radius())) - 1;  // whole offsets strictly within the radius
    double w0 = 1;
    const std::vector<float> u = axis_weights(kernel, m, w0);
    ZeroedBuffer<float> scratch;  // the convolution's other buffer, reused grid after grid
    const int pad = m + 1;  // the stencil's spread and a ring of zeros that trilinear reads towards
    for (const ShadedVolume& v : volumes) {
        if (v.grid->active_voxel_count() == 0) continue;
        smallest_spacing_ = std::min(smallest_spacing_, smallest_voxel_spacing(*v.grid));
        // The coarsest level needed to stay within kMostVoxels.
        Grid grid = *v.grid;
        std::array<int32_t, 6> b = grid.index_bbox();
        auto side = [&](int a) { return uint64_t(int64_t(b[a + 3]) - b[a] + 1 + 2 * pad); };
        auto count = [&] { return double(side(0)) * double(side(1)) * double(side(2)); };  // no wrapping
        for (int k = 1; count() > double(kMostVoxels); ++k) {
            grid = v.grid->level(k, LevelReduction::MeanOverBackground);
            b = grid.index_bbox();
        }
        auto lattice = std::make_unique<Lattice>();
        Lattice& l = *lattice;
        for (int a = 0; a < 3; ++a) l.n[a] = b[a + 3] - b[a] + 1 + 2 * pad;
        // Zero pages from the kernel, faulted in on all cores: most of a box is air, which stays 0.
        l.departure = ZeroedBuffer<float>(size_t(count()));
        const double background = grid.background();
        const std::vector<VoxelBlock>& blocks = grid.blocks();
        tbb::parallel_for(size_t(0), blocks.size(), [&](size_t bi) {
            const VoxelBlock& block = blocks[bi];
            for (int offset = 0; offset < VoxelBlock::kSize; ++offset) {
                if (!block.active(offset)) continue;
                const double d = double(block.value(offset)) - background;
                if (!std::isfinite(d)) continue;
                const int i = block.origin[0] + (offset >> 6) - b[0] + pad, j = block.origin[1] + ((offset >> 3) & 7) - b[1] + pad,
                          k = block.origin[2] + (offset & 7) - b[2] + pad;
                l.departure[l.index(i, j, k)] = float(d * w0);  // w0 once here, u along each axis below
            }
        });
        convolve(l.departure, scratch, l.n, u, m);

        // Relative position -> world -> index -> lattice (index less the box's corner, plus the pad).
        const Mat4 to_index = *grid.index_to_world().inverse();
        for (int r = 0; r < 3; ++r) {
            const double at_origin = to_index.m[r][0] * origin.x + to_index.m[r][1] * origin.y + to_index.m[r][2] * origin.z + to_index.m[r][3];
            for (int c = 0; c < 3; ++c) l.to_lattice[r][c] = float(to_index.m[r][c]);
            l.to_lattice[r][3] = float(at_origin - b[r] + pad);
        }
        l.scale = float(v.density_scale);
        l.offset = float(background * v.density_scale);
        l.table = std::make_unique<ClassificationTable>(*v.transfer_function, v.transfer_function->unit_distance);
        if (v.clip && !v.clip->keeps_everything()) l.clip.emplace(*v.clip, origin, smallest_voxel_spacing(grid));
        l.map_occupancy();
        const Mat4& to_world = grid.index_to_world();
        for (int corner = 0; corner < 8; ++corner) {
            const Vec3 index{double((corner & 4) ? b[3] + pad : b[0] - pad), double((corner & 2) ? b[4] + pad : b[1] - pad),
                             double((corner & 1) ? b[5] + pad : b[2] - pad)};
            corners_.push_back(to_world.transform_point(index) - origin);
        }
        lattices_.push_back(std::move(lattice));
    }
}

ExtinctionField::~ExtinctionField() = default;

template <class Fn>
void ExtinctionField::densities(const Vec3x8& p, Fn&& fn) const {
    for (const auto& lattice : lattices_) {
        const Lattice& l = *lattice;
        float8 x[3];
        int8x inside = broadcast8(0.0f) == broadcast8(0.0f);
        int8x base = {};
        float8 f[3];
        for (int a = 0; a < 3; ++a) {
            const float(&row)[4] = l.to_lattice[a];
            x[a] = p.x * row[0] + p.y * row[1] + p.z * row[2] + row[3];
            inside &= (x[a] >= 0.0f) & (x[a] <= float(l.n[a] - 1));
            const float8 clamped = clamp8(x[a], 0.0f, float(l.n[a] - 2));
            const int8x i0 = __builtin_convertvector(clamped, int8x);
            f[a] = clamp8(x[a] - __builtin_convertvector(i0, float8), 0.0f, 1.0f);
            base = a == 0 ? i0 : base * l.n[a] + i0;
        }
        if (!any8(inside)) continue;
        int8x brick = {};
        for (int a = 0; a < 3; ++a) {
            const int8x b = __builtin_convertvector(clamp8(x[a], 0.0f, float(l.n[a] - 2)) * (1.0f / Lattice::kBrick), int8x);
            brick = a == 0 ? b : brick * l.bricks[a] + b;
        }
        inside &= gather8(l.occupied.data(), inside ? brick : int8x{}) > 0.0f;
        if (!any8(inside)) continue;
        base = inside ? base : int8x{};
        const int sk = 1, sj = l.n[2], si = l.n[1] * l.n[2];
        const float* d = l.departure.data();
        auto lerp = [](float8 a, float8 b, float8 t) { return a + t * (b - a); };
        auto edge = [&](int offset) { return lerp(gather8(d + offset, base), gather8(d + offset + sk, base), f[2]); };
        const float8 near_i = lerp(edge(0), edge(sj), f[1]), far_i = lerp(edge(si), edge(si + sj), f[1]);
        const float8 departure = lerp(near_i, far_i, f[0]);
        int8x reached = inside & (departure != 0.0f);
        if (l.clip) reached &= l.clip->inside<float8>(p);
        if (!any8(reached)) continue;
        fn(*l.table, departure * l.scale + l.offset, reached);
    }
}

float8 ExtinctionField::at(const Vec3x8& p) const {
    float8 sum = broadcast8(0.0f);
    densities(p, [&](const ClassificationTable& table, float8 density, int8x reached) {
        sum += select8(reached, table.extinction(density), broadcast8(0.0f));
    });
    return sum;
}

ExtinctionField::Medium ExtinctionField::medium(const Vec3x8& p) const {
    Medium out{broadcast8(0.0f), {broadcast8(0.0f), broadcast8(0.0f), broadcast8(0.0f)}};
    densities(p, [&](const ClassificationTable& table, float8 density, int8x reached) {
        const ClassificationTable::Samples s = table(density);
        const float8 sigma = select8(reached, s.extinction, broadcast8(0.0f));
        out.extinction += sigma;
        out.albedo = out.albedo + Vec3x8{s.red, s.green, s.blue} * sigma;
    });
    const float8 per = select8(out.extinction > 0.0f, 1.0f / out.extinction, broadcast8(0.0f));
    out.albedo = out.albedo * per;
    return out;
}

}  // namespace pcvr
