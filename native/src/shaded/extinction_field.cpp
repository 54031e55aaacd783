#include "shaded/extinction_field.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <optional>

#include "pcvr/errors.h"
#include "pcvr/transfer_function.h"
#include "shaded/shaded_levels.h"

namespace pcvr {

/// One grid resampled: departures from the background at its voxel centres, [i][j][k] with k fastest.
struct ExtinctionField::Lattice {
    int n[3] = {0, 0, 0};
    std::vector<float> departure;
    float to_lattice[3][4];  // relative position -> lattice coordinates
    float scale = 1, offset = 0;  // density = departure * scale + offset
    std::unique_ptr<ClassificationTable> table;
    std::optional<SampleClip> clip;

    size_t index(int i, int j, int k) const { return (size_t(i) * n[1] + j) * n[2] + k; }
};

namespace {

/// The kernel's weights at whole offsets -m..m along one axis (the offsets within its radius lie in that
/// cube), such that the weight at offset o is w0 u(ox) u(oy) u(oz): true of the Gaussians (products of
/// their axes' factors, truncated beyond the cube) and of the kernels that reach only the centre.
std::vector<double> axis_weights(const Kernel& kernel, int m, double& w0) {
    const double R = kernel.radius();
    auto weight = [&](double x, double y, double z) {
        const double r = std::sqrt(x * x + y * y + z * z);
        return r < R ? kernel.value(r) : 0.0;
    };
    w0 = weight(0, 0, 0);
    std::vector<double> u(2 * m + 1);
    for (int o = -m; o <= m; ++o) u[o + m] = weight(o, 0, 0) / w0;
    for (int x = -m; x <= m; ++x)
        for (int y = -m; y <= m; ++y)
            for (int z = -m; z <= m; ++z)
                if (std::abs(weight(x, y, z) - w0 * u[x + m] * u[y + m] * u[z + m]) > 1e-9 * w0)
                    throw Error(std::string("shadows: kernel '") + kernel.name() + "' is not separable at whole offsets");
    return u;
}

/// Convolves `values` along axis `axis` with weights u (offsets -m..m), zero beyond the ends: row by row
/// of the faster axes, so that the inner loop runs over contiguous memory.
void convolve_axis(std::vector<float>& values, const int (&n)[3], int axis, const std::vector<double>& u, int m) {
    if (m == 0) return;
    const size_t run = axis == 2 ? 1 : axis == 1 ? size_t(n[2]) : size_t(n[1]) * n[2];  // the faster axes
    const int length = n[axis];
    const size_t slabs = values.size() / (run * length);
    std::vector<float> out(values.size(), 0.0f);
    if (run == 1) {  // along the contiguous axis: a line at a time
        tbb::parallel_for(size_t(0), slabs, [&](size_t line) {
            const float* from = values.data() + line * length;
            float* to = out.data() + line * length;
            for (int t = 0; t < length; ++t)
                for (int o = std::max(-m, -t); o <= std::min(m, length - 1 - t); ++o) to[t] += float(u[o + m]) * from[t + o];
        });
        values.swap(out);
        return;
    }
    tbb::parallel_for(size_t(0), slabs * length, [&](size_t row) {
        const size_t slab = row / length;
        const int t = int(row % length);
        float* to = out.data() + row * run;
        for (int o = std::max(-m, -t); o <= std::min(m, length - 1 - t); ++o) {
            const float w = float(u[o + m]);
            const float* from = values.data() + (slab * length + t + o) * run;
            for (size_t e = 0; e < run; ++e) to[e] += w * from[e];
        }
    });
    values.swap(out);
}

}  // namespace

ExtinctionField::ExtinctionField(const std::vector<ShadedVolume>& volumes, const Kernel& kernel, const Vec3& origin) {
    const int m = int(std::ceil(kernel.radius())) - 1;  // whole offsets strictly within the radius
    double w0 = 1;
    const std::vector<double> u = axis_weights(kernel, m, w0);
    const int pad = m + 1;  // the stencil's spread and a ring of zeros that trilinear reads towards
    for (const ShadedVolume& v : volumes) {
        if (v.grid->active_voxel_count() == 0) continue;
        smallest_spacing_ = std::min(smallest_spacing_, smallest_voxel_spacing(*v.grid));
        // The coarsest level needed to stay within kMostVoxels.
        Grid grid = *v.grid;
        std::array<int32_t, 6> b = grid.index_bbox();
        auto count = [&] { return uint64_t(b[3] - b[0] + 1 + 2 * pad) * uint64_t(b[4] - b[1] + 1 + 2 * pad) * uint64_t(b[5] - b[2] + 1 + 2 * pad); };
        for (int k = 1; count() > kMostVoxels; ++k) {
            grid = v.grid->level(k, LevelReduction::MeanOverBackground);
            b = grid.index_bbox();
        }
        auto lattice = std::make_unique<Lattice>();
        Lattice& l = *lattice;
        for (int a = 0; a < 3; ++a) l.n[a] = b[a + 3] - b[a] + 1 + 2 * pad;
        l.departure.assign(count(), 0.0f);
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
        for (int axis = 0; axis < 3; ++axis) convolve_axis(l.departure, l.n, axis, u, m);

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

float8 ExtinctionField::at(const Vec3x8& p) const {
    float8 sum = broadcast8(0.0f);
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
        const float8 extinction = (*l.table)(departure * l.scale + l.offset).extinction;
        sum += select8(reached, extinction, broadcast8(0.0f));
    }
    return sum;
}

}  // namespace pcvr
