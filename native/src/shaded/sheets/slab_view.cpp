/// @file slab_view.cpp
/// @brief SlabView's per-view preparation of one grid, and what it answers about a block: the projection's
/// constants, the subgrid footprint of orthographic views, how deep a kernel reaches, the order of a block's
/// voxels by depth, the blocks linearised for perspective views, and a block's front, nearest depth and voxels left.
///
/// Apart from the deposit (slab_splat.cpp), which splats voxels sheet after sheet with what is prepared here: this
/// runs once per grid and view (and once per block for its bounds), the deposit once per voxel and slab.
#include "shaded/sheets/slab_splat.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

#include <tbb/parallel_for.h>

#include "pcvr/errors.h"
#include "volume/block_voxels.h"

namespace pcvr {

double SheetLattice::round_scale(const Mat4& index_to_world) const {
    const double round = pcvr::round_scale(metric, index_to_world);
    return spherical || !is_identity(metric) ? round : 0.0;
}

double depth_per_voxel(const ViewProjection& projection, const Grid& grid, const SheetLattice& sheets) {
    if (const double round = sheets.round_scale(grid.index_to_world()); round > 0) return round;
    Footprint centre;
    const auto [i0, j0, k0, i1, j1, k1] = grid.index_bbox();
    const Vec3 middle{0.5 * (i0 + i1), 0.5 * (j0 + j1), 0.5 * (k0 + k1)};
    // Behind the eye there is no central ray through the grid: fall back to the steepest direction.
    if (!projection.footprint_unclipped(middle, centre))
        return sheets.spherical ? largest_singular_value(grid.index_to_world()) : length(projection.depth_gradient());
    return sheets.spherical ? centre.line_scale : centre.depth_per_index;
}

SlabView::SlabView(const Grid& grid, const Camera& camera, const SheetLattice& sheets, const SlabSplatParams& params)
    : grid_(&grid), projection_(camera, grid.index_to_world()), sheets_(sheets), params_(params) {
    if (!params.kernel || !params.table || !params.profile || params.stride < 1)
        throw InvalidArgument("SlabView: kernel, footprint table, depth profile and a stride >= 1 are required");
    const Mat4& w = grid.index_to_world();
    if (sheets.spherical) {
        order_gradient_ = projection_.depth_gradient();
        order_offset_ = projection_.depth({0, 0, 0});
    } else {
        const Vec3& a = sheets.planes.gradient;
        order_gradient_ = Vec3{dot(w.column(0), a), dot(w.column(1), a), dot(w.column(2), a)};
        order_offset_ = dot(w.column(3), a) + sheets.planes.offset;
        const Vec3 ray = projection_.index_ray(0, 0).direction;
        plane_kappa_ = dot(order_gradient_, ray) / length(ray);
    }
    round_scale_ = sheets.round_scale(w);
    const Vec3& n = order_gradient_;
    if (sheets.spherical) {
        if (round_scale_ > 0) {
            // Index space, where the spheres are round too: -z along the depth gradient, the eye at 0.
            const Vec3 axis = n * (1.0 / length(n));
            Vec3 side[2];
            complete_frame(axis, side[0], side[1]);
            const Vec3 rows[3] = {side[0], side[1], axis * -1.0};
            const Vec3& eye = projection_.eye();
            for (int r = 0; r < 3; ++r) {
                order_frame_.m[r][0] = rows[r].x, order_frame_.m[r][1] = rows[r].y, order_frame_.m[r][2] = rows[r].z;
                order_frame_.m[r][3] = -dot(rows[r], eye);
            }
            order_scale_ = round_scale_ / length(n);
        } else {
            order_frame_ = camera.world_to_camera() * grid.index_to_world();
            order_scale_ = length(camera.world_to_camera().inverse()->column(2));  // world length of a camera unit
        }
    }
    // A kernel's reach in the sheet parameter: along the depth gradient for planes; for spheres the
    // longest metric length of an index-space radius (the largest singular value of the linear part).
    depth_reach_ = params.kernel->radius() *
                   (sheets.spherical ? (round_scale_ > 0 ? round_scale_ : largest_singular_value(sheets.metric * w))
                                     : length(n));
    slabs_per_voxel_ = int(std::ceil(2.0 * depth_reach_ / sheets.spacing - 1e-9)) + 1;
    if (!(slabs_per_voxel_ <= kMostSlabs)) {
        const double factor = 2.0 * depth_reach_ / (kMostSlabs - 1) / sheets.spacing;
        throw InvalidArgument("sheet spacing too small for grid '" + grid.name() + "': its kernel would span " +
                              std::to_string(slabs_per_voxel_) + " sheets (at most " + std::to_string(kMostSlabs) +
                              "; its voxels are long in depth): make sheet_spacing at least " + std::to_string(factor) +
                              " times larger");
    }

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
        // Smooth kernels' windows come whole from a phase table, as for X-ray; the box's rim would blur.
        const double det = shape_.qxx * shape_.qyy - shape_.qxy * shape_.qxy;
        const double radius = params.kernel->radius();
        const double extent = std::max(radius * std::sqrt(shape_.qyy / det), radius * std::sqrt(shape_.qxx / det));
        const int half_width = std::max(2, int(std::ceil(extent - 1e-4)));
        if (params.mode == SlabMode::Footprint && params.kernel->smooth_footprint() && 2 * half_width <= kMostWindow)
            window_ = std::make_unique<PhaseFootprintTable>(*params.kernel, shape_.qxx, shape_.qxy, shape_.qyy, half_width);
    }
}

void SlabView::linearise(const std::vector<uint32_t>& blocks) {
    if (projection_.orthographic() || round_scale_ <= 0 || params_.mode != SlabMode::Footprint || blocks.empty()) return;
    const std::vector<VoxelBlock>& all = grid_->blocks();
    std::vector<std::optional<BlockLinearisation>> made(blocks.size());
    tbb::parallel_for(size_t(0), blocks.size(), [&](size_t b) {
        const VoxelBlock& block = all[blocks[b]];
        // Every kernel of the block in front of the eye, as a footprint needs (deposit's condition).
        if (nearest_depth(block) > depth_reach_) made[b] = linearise_block(block, projection_, params_.stride, 0.0, 0.0, false, 0.0);
    });
    linear_slot_.assign(all.size(), -1);
    for (size_t b = 0; b < blocks.size(); ++b)
        if (made[b]) {
            linear_slot_[blocks[b]] = int32_t(linearised_.size());
            linearised_.push_back(*made[b]);
        }
}

uint64_t SlabView::voxels_left(const VoxelBlock& block, int first, const VoxelMask* splat) const {
    if (!splat && all_active(block)) return uint64_t(VoxelBlock::kSize - first);
    const VoxelMask& mask = splat ? *splat : block.mask;
    uint64_t n = 0;
    for (int rank = first; rank < VoxelBlock::kSize; ++rank) n += contains(mask, order_.offset[rank]);
    return n;
}

double SlabView::limit_scale(const VoxelBlock& block) const {
    if (!sheets_.spherical) return 1.0;
    // The block's voxel centres in the order frame: their largest cosine to the axis is at most the
    // largest depth over the hypotenuse with the smallest distance from the axis.
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p{double(block.origin[0] + ((corner & 1) ? VoxelBlock::kDim - 1 : 0)),
                     double(block.origin[1] + ((corner & 2) ? VoxelBlock::kDim - 1 : 0)),
                     double(block.origin[2] + ((corner & 4) ? VoxelBlock::kDim - 1 : 0))};
        const Vec3 c = order_frame_.transform_point(p);
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
    }
    auto nearest_to_zero = [](double a, double b) { return a <= 0 && b >= 0 ? 0.0 : std::min(std::abs(a), std::abs(b)); };
    const double off_axis = std::hypot(nearest_to_zero(lo[0], hi[0]), nearest_to_zero(lo[1], hi[1]));
    const double deepest = std::max(-lo[2], 1e-300);  // depth = -z
    return deepest / std::hypot(deepest, off_axis) / order_scale_;
}

namespace {

/// The least of an affine function over a block's voxel centres, given its gradient and its value at
/// the origin: the origin plus the gradient's negative parts.
double least_in_block(const Vec3& gradient, double at_origin) {
    const double span = VoxelBlock::kDim - 1;
    return at_origin + span * (std::min(gradient.x, 0.0) + std::min(gradient.y, 0.0) + std::min(gradient.z, 0.0));
}

}  // namespace

double SlabView::front(const VoxelBlock& block) const {
    const double nearest = least_in_block(order_gradient_, order_depth(block));
    // Spheres: a voxel's distance is its planar depth over its cosine to the axis, at least this.
    return (sheets_.spherical ? std::max(0.0, nearest) / limit_scale(block) : nearest) - depth_reach_;
}

double SlabView::nearest_depth(const VoxelBlock& block) const {
    const Vec3 origin{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])};
    return least_in_block(projection_.depth_gradient(), projection_.depth(origin));
}

}  // namespace pcvr
