#include "slab_splat.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>

#include "block_voxels.h"
#include "pcvr/lanes.h"
#include "pcvr/errors.h"

namespace pcvr {

namespace {

constexpr int kBatch = 8;
/// Sheets one kernel may span (its deposit keeps a pointer per sheet on the stack).
constexpr int kMostSlabs = 64;

inline void add8(float* p, float8 v) { store8(p, load8(p) + v); }

/// Eight voxels projected onto a ring: everything the deposit needs, per lane, in ring node units.
struct SlabBatch {
    float cx[kBatch], cy[kBatch];                // centre
    float qxx[kBatch], qxy[kBatch], qyy[kBatch];  // rho^2 per node offset
    float ext_x[kBatch], ext_y[kBatch];          // half-widths of the ellipse's bounding box
    float amp[kBatch];                           // value * density scale * world length per index length
    float s0[kBatch];                            // s (index units along the ray) of the first slab's front, at the centre
    float s_dx[kBatch], s_dy[kBatch];            // change of s per node offset
    float s_step[kBatch];                        // s between consecutive slab boundaries
    int64_t first_sheet[kBatch];
    uint32_t live = 0;                           // lanes holding a voxel to splat
};

/// The values of ranks [first, first + 8) (0 for ranks at or past `last`, inactive or non-finite voxels).
float8 batch_values(const VoxelBlock& block, const SlabView::DepthOrder& order, int first, int last, bool full) {
    float8 v;
    for (int l = 0; l < kBatch; ++l) {
        const int rank = first + l;
        float value = 0.0f;
        if (rank < last) {
            const int offset = order.offset[rank];
            if (full || block.active(offset)) value = block.value(offset);
        }
        v[l] = std::isfinite(value) ? value : 0.0f;
    }
    return v;
}

uint32_t non_zero_lanes(float8 v) {
    uint32_t live = 0;
    for (int l = 0; l < kBatch; ++l) live |= uint32_t(v[l] != 0.0f) << l;
    return live;
}

}  // namespace

double depth_per_voxel(const ViewProjection& projection, const Grid& grid) {
    Footprint centre;
    const auto [i0, j0, k0, i1, j1, k1] = grid.index_bbox();
    const Vec3 middle{0.5 * (i0 + i1), 0.5 * (j0 + j1), 0.5 * (k0 + k1)};
    // Behind the eye there is no central ray through the grid: fall back to the steepest direction.
    return projection.footprint_unclipped(middle, centre) ? centre.depth_per_index : length(projection.depth_gradient());
}

SlabView::SlabView(const Grid& grid, const Camera& camera, const SheetLattice& sheets, const SlabSplatParams& params)
    : grid_(&grid), projection_(camera, grid.index_to_world()), sheets_(sheets), params_(params) {
    if (!params.kernel || !params.table || !params.profile || params.stride < 1)
        throw InvalidArgument("SlabView: kernel, footprint table, depth profile and a stride >= 1 are required");
    const Vec3& n = projection_.depth_gradient();
    depth_reach_ = params.kernel->radius() * length(n);
    slabs_per_voxel_ = int(std::ceil(2.0 * depth_reach_ / sheets.spacing - 1e-9)) + 1;
    if (!(slabs_per_voxel_ <= kMostSlabs))
        throw InvalidArgument("sheet spacing too small: a kernel would span " + std::to_string(slabs_per_voxel_) +
                              " sheets (at most " + std::to_string(kMostSlabs) + ")");

    // Depth order of a block's voxels: depth is affine in index space, so one order serves every block.
    std::vector<int32_t> offsets(VoxelBlock::kSize);
    std::iota(offsets.begin(), offsets.end(), 0);
    auto depth_of = [&](int32_t o) { return dot(n, Vec3{double(o >> 6), double((o >> 3) & 7), double(o & 7)}); };
    std::stable_sort(offsets.begin(), offsets.end(), [&](int32_t a, int32_t b) { return depth_of(a) < depth_of(b); });
    const size_t padded = VoxelBlock::kSize + kBatch;
    order_.offset.assign(padded, 0);
    order_.i.assign(padded, 0.0f);
    order_.j.assign(padded, 0.0f);
    order_.k.assign(padded, 0.0f);
    order_.depth.assign(padded, INFINITY);
    for (int r = 0; r < VoxelBlock::kSize; ++r) {
        const int32_t o = offsets[r];
        order_.offset[r] = o;
        order_.i[r] = float(o >> 6);
        order_.j[r] = float((o >> 3) & 7);
        order_.k[r] = float(o & 7);
        order_.depth[r] = float(depth_of(o));
    }

    if (projection_.orthographic()) {
        // Differences of exact projections, as the X-ray splat does; the shape in subgrid node units.
        const double inv_stride = 1.0 / params.stride;
        Footprint f0, fi, fj, fk;
        projection_.footprint_unclipped({0, 0, 0}, f0);
        projection_.footprint_unclipped({1, 0, 0}, fi);
        projection_.footprint_unclipped({0, 1, 0}, fj);
        projection_.footprint_unclipped({0, 0, 1}, fk);
        node_gx_ = Vec3{fi.px - f0.px, fj.px - f0.px, fk.px - f0.px} * inv_stride;
        node_gy_ = Vec3{fi.py - f0.py, fj.py - f0.py, fk.py - f0.py} * inv_stride;
        node_x0_ = f0.px * inv_stride;
        node_y0_ = f0.py * inv_stride;
        shape_ = f0;
        const double s2 = double(params.stride) * params.stride;
        shape_.qxx *= s2;
        shape_.qxy *= s2;
        shape_.qyy *= s2;
        shape_.depth_dx *= params.stride;
        shape_.depth_dy *= params.stride;
    }
}

double SlabView::origin_depth(const VoxelBlock& block) const {
    return projection_.depth(Vec3{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])});
}

namespace {

/// The slab footprints of one projected voxel (lane l of `b`) added into `ring`, clipped to it.
/// Returns false when its window misses the ring or lies on occluded nodes (then `occluded` is set).
bool deposit_lane(const SlabBatch& b, int l, const SlabSplatParams& params, int slabs, SheetRing& ring,
                  int64_t first_open_sheet, const OcclusionMap* occlusion, bool& occluded) {
    const float cx = b.cx[l], cy = b.cy[l];
    const bool spread = params.mode == SlabMode::BilinearSpread;
    int c0, c1, r0, r1;
    if (spread) {
        c0 = clamp_to_int(std::floor(cx), -2, ring.columns());
        r0 = clamp_to_int(std::floor(cy), -2, ring.rows());
        c1 = c0 + 1, r1 = r0 + 1;
    } else {
        c0 = clamp_to_int(std::ceil(cx - b.ext_x[l]), -1, ring.columns());
        c1 = clamp_to_int(std::floor(cx + b.ext_x[l]), -1, ring.columns());
        r0 = clamp_to_int(std::ceil(cy - b.ext_y[l]), -1, ring.rows());
        r1 = clamp_to_int(std::floor(cy + b.ext_y[l]), -1, ring.rows());
    }
    const int cc0 = std::max(c0, 0), cc1 = std::min(c1, ring.columns() - 1);
    const int rr0 = std::max(r0, 0), rr1 = std::min(r1, ring.rows() - 1);
    if (cc0 > cc1 || rr0 > rr1) return false;
    if (occlusion && occlusion->covered(cc0, rr0, cc1, rr1)) {
        occluded = true;
        return false;
    }

    const DepthProfile& depth = *params.profile;
    auto D = [&](float s) { return depth(s); };
    const int64_t first_sheet = b.first_sheet[l];
    const int k_begin = int(std::clamp<int64_t>(first_open_sheet - first_sheet, 0, slabs));
    if (k_begin >= slabs) return false;
    const size_t pitch = ring.pitch();
    const float amp = b.amp[l];
    const Box window{cc0, rr0, cc1, rr1};
    for (int k = k_begin; k < slabs; ++k) ring.touch(first_sheet + k, window);

    if (spread) {
        // The slab's share of the footprint integral, on the 2 x 2 nodes around the centre.
        const float fx = cx - float(c0), fy = cy - float(r0);
        const float w[2][2] = {{(1 - fx) * (1 - fy), fx * (1 - fy)}, {(1 - fx) * fy, fx * fy}};
        float front = D(b.s0[l] + k_begin * b.s_step[l]);
        for (int k = k_begin; k < slabs; ++k) {
            const float back = D(b.s0[l] + (k + 1) * b.s_step[l]);
            const float mass = amp * (back - front);
            front = back;
            if (mass == 0.0f) continue;
            float* sheet = ring.sheet(first_sheet + k);
            for (int j = 0; j < 2; ++j)
                for (int i = 0; i < 2; ++i)
                    if (c0 + i >= cc0 && c0 + i <= cc1 && r0 + j >= rr0 && r0 + j <= rr1)
                        sheet[size_t(r0 + j) * pitch + c0 + i] += mass * w[j][i];
        }
        return true;
    }

    const FootprintTable& table = *params.table;
    const float qxx = b.qxx[l], qxy2 = 2.0f * b.qxy[l], qyy = b.qyy[l];
    const float s_dx = b.s_dx[l], s_dy = b.s_dy[l], s_step = b.s_step[l];
    const float8 lanes = lane_index8();
    const auto clamp_unit = [](float8 t) { return clamp8(t, -1.0f, 1.0f); };
    const auto abs8_ = [](float8 t) { return abs8(t); };
    const float8 scale = broadcast8(table.scale()), last_index = broadcast8(table.max_index());
    float* sheets[kMostSlabs];
    const int count = slabs;
    for (int k = k_begin; k < count; ++k) sheets[k] = ring.sheet(first_sheet + k);
    // Sheets perpendicular to the rays through the kernel (isotropic voxels, orthographic view): each
    // slab's share is the same at every tap, D evaluated once per slab. Aligned means that s moves by
    // less than 1e-4 index units across the footprint (D changes by less than 1e-4 there).
    const bool aligned = std::abs(s_dx) * b.ext_x[l] + std::abs(s_dy) * b.ext_y[l] < 1e-4f;
    float share[kMostSlabs];
    if (aligned) {
        float front = D(b.s0[l] + k_begin * s_step);
        for (int k = k_begin; k < count; ++k) {
            const float back = D(b.s0[l] + (k + 1) * s_step);
            share[k] = back - front;
            front = back;
        }
    }
    for (int r = rr0; r <= rr1; ++r) {
        const float dy = float(r) - cy;
        const size_t row = size_t(r) * pitch;
        for (int col = cc0; col <= cc1; col += kBatch) {
            const float8 dx = broadcast8(float(col) - cx) + lanes;
            const int8x inside = lanes <= broadcast8(float(cc1 - col));
            const float8 rho2 = (broadcast8(qxx) * dx + broadcast8(qxy2 * dy)) * dx + broadcast8(qyy * dy * dy);
            const int8x index = __builtin_convertvector(min8(max8(rho2 * scale, broadcast8(0.0f)), last_index), int8x);
            const float8 weight = select8(inside, gather8(table.data(), index) * amp, broadcast8(0.0f));
            if (aligned) {
                for (int k = k_begin; k < count; ++k) add8(sheets[k] + row + col, weight * share[k]);
            } else {
                float8 s = broadcast8(b.s0[l] + k_begin * s_step + s_dy * dy) + broadcast8(s_dx) * dx;
                float8 front = depth(s, clamp_unit, abs8_);
                for (int k = k_begin; k < count; ++k) {
                    s += s_step;
                    const float8 back = depth(s, clamp_unit, abs8_);
                    add8(sheets[k] + row + col, weight * (back - front));
                    front = back;
                }
            }
        }
    }
    return true;
}

}  // namespace

DepositCounts SlabView::deposit(const VoxelBlock& block, int first, int last, SheetRing& ring, const RingPlacement& placement,
                                int64_t first_open_sheet, const OcclusionMap* occlusion) const {
    DepositCounts counts;
    if (first >= last) return counts;
    const bool full = all_active(block);
    const double stride = params_.stride, inv_stride = 1.0 / stride;
    const double spacing = sheets_.spacing, inv_spacing = 1.0 / spacing;
    const Vec3 origin{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])};
    // Depths relative to the slab holding the block's origin keep the per-voxel arithmetic in small floats.
    const double origin_slabs = (origin_depth(block) - sheets_.first_depth) * inv_spacing;
    const int64_t base_sheet = int64_t(std::floor(origin_slabs));
    const float base_fraction = float(origin_slabs - double(base_sheet));
    const float reach_slabs = float(depth_reach_ * inv_spacing);
    const bool spread = params_.mode == SlabMode::BilinearSpread;
    const float density_scale = params_.density_scale;

    SlabBatch b;
    for (int batch = first; batch < last; batch += kBatch) {
        const float8 v = batch_values(block, order_, batch, last, full);
        b.live = non_zero_lanes(v);
        if (!b.live) continue;
        if (projection_.orthographic()) {
            const float8 i = load8(order_.i.data() + batch), j = load8(order_.j.data() + batch), k = load8(order_.k.data() + batch);
            const float ox = float(node_x0_ + dot(node_gx_, origin) - placement.node_x0);
            const float oy = float(node_y0_ + dot(node_gy_, origin) - placement.node_y0);
            const float8 cx = ox + float(node_gx_.x) * i + float(node_gx_.y) * j + float(node_gx_.z) * k;
            const float8 cy = oy + float(node_gy_.x) * i + float(node_gy_.y) * j + float(node_gy_.z) * k;
            // Slab units: the first slab a voxel reaches, and where its centre lies relative to it.
            const float8 centre = base_fraction + load8(order_.depth.data() + batch) * float(inv_spacing);
            const float kappa = float(shape_.depth_per_index);
            for (int l = 0; l < kBatch; ++l) {
                const float front = std::floor(centre[l] - reach_slabs);
                b.cx[l] = cx[l];
                b.cy[l] = cy[l];
                b.first_sheet[l] = base_sheet + int64_t(front);
                b.s0[l] = (front - centre[l]) * float(spacing) / kappa;
            }
            const double det = shape_.qxx * shape_.qyy - shape_.qxy * shape_.qxy;
            const float ext_x = float(params_.kernel->radius() * std::sqrt(shape_.qyy / det));
            const float ext_y = float(params_.kernel->radius() * std::sqrt(shape_.qxx / det));
            const float amp_per_value = float(density_scale * shape_.line_scale * (spread ? 1.0 / std::sqrt(det) : 1.0));
            for (int l = 0; l < kBatch; ++l) {
                b.qxx[l] = float(shape_.qxx);
                b.qxy[l] = float(shape_.qxy);
                b.qyy[l] = float(shape_.qyy);
                b.ext_x[l] = ext_x;
                b.ext_y[l] = ext_y;
                b.amp[l] = v[l] * amp_per_value;
                b.s_dx[l] = float(-shape_.depth_dx / kappa);
                b.s_dy[l] = float(-shape_.depth_dy / kappa);
                b.s_step[l] = float(spacing / kappa);
            }
        } else {
            const Mat4& m = projection_.index_to_clip();
            for (int half = 0; half < 2; ++half) {
                double4 x, y, z;
                for (int l = 0; l < 4; ++l) {
                    const int rank = batch + 4 * half + l;
                    x[l] = origin.x + order_.i[rank];
                    y[l] = origin.y + order_.j[rank];
                    z[l] = origin.z + order_.k[rank];
                }
                auto row = [&](int r) { return x * m.m[r][0] + y * m.m[r][1] + z * m.m[r][2] + m.m[r][3]; };
                const double4 clip_w = row(3);
                const FootprintLanes<double4> f = projection_.footprint_lanes(x, y, z, row(0), row(1), clip_w, sqrt4);
                for (int l = 0; l < 4; ++l) {
                    const int lane = 4 * half + l;
                    // A footprint needs the whole kernel in front of the eye.
                    if (!(clip_w[l] > 0) || !(f.depth[l] > depth_reach_)) {
                        b.live &= ~(1u << lane);
                        continue;
                    }
                    const double qxx = f.qxx[l] * stride * stride, qxy = f.qxy[l] * stride * stride, qyy = f.qyy[l] * stride * stride;
                    const double det = qxx * qyy - qxy * qxy, kappa = f.depth_per_index[l];
                    const double slabs = (f.depth[l] - sheets_.first_depth) * inv_spacing;
                    const double front = std::floor(slabs - depth_reach_ * inv_spacing);
                    b.cx[lane] = float(f.px[l] * inv_stride - placement.node_x0);
                    b.cy[lane] = float(f.py[l] * inv_stride - placement.node_y0);
                    b.qxx[lane] = float(qxx);
                    b.qxy[lane] = float(qxy);
                    b.qyy[lane] = float(qyy);
                    b.ext_x[lane] = float(params_.kernel->radius() * std::sqrt(qyy / det));
                    b.ext_y[lane] = float(params_.kernel->radius() * std::sqrt(qxx / det));
                    b.amp[lane] = float(v[lane] * density_scale * f.line_scale[l] * (spread ? 1.0 / std::sqrt(det) : 1.0));
                    b.first_sheet[lane] = int64_t(front);
                    b.s0[lane] = float((front - slabs) * spacing / kappa);
                    b.s_dx[lane] = float(-f.depth_dx[l] * stride / kappa);
                    b.s_dy[lane] = float(-f.depth_dy[l] * stride / kappa);
                    b.s_step[lane] = float(spacing / kappa);
                }
            }
        }
        for (uint32_t todo = b.live; todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            bool occluded = false;
            if (deposit_lane(b, l, params_, slabs_per_voxel_, ring, first_open_sheet, occlusion, occluded))
                ++counts.splatted;
            else if (occluded)
                ++counts.occluded;
        }
    }
    return counts;
}

}  // namespace pcvr
