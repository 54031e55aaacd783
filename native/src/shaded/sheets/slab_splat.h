/// @file slab_splat.h
/// @brief Splatting voxels slab by slab into a tile's sheet ring: the per-view preparation of one grid
/// (SlabView; slab_view.cpp) and the per-deposit work (SlabView::deposit; slab_splat.cpp).
///
/// A SlabView holds everything about one grid seen from one camera that does not change from sheet to
/// sheet or tile to tile: the projection, the subgrid stride, the footprint and depth-profile tables,
/// how deep a kernel reaches, and the order of a block's voxels by depth (the same for every block,
/// since depth is affine in index space). A deposit splats a run of a block's voxels, in that order,
/// into the sheets of a SheetRing that one tile owns, clipped to the ring: each voxel adds
/// amplitude * P(rho^2) * (D(s_hi) - D(s_lo)) (slab_footprint.h) to every node of its footprint in
/// each of the slabs_per_voxel() sheets from its first. Eight voxels are projected at once (in double
/// for perspective views, with ViewProjection::footprint_lanes; affinely in float for orthographic
/// ones), then each one's footprint is added row by row in vectors of eight nodes.
///
/// | mode            | per voxel and slab                                                     |
/// |-----------------|------------------------------------------------------------------------|
/// | Footprint       | every node within the kernel's ellipse (regular: stride 1; pcvr: the subgrid) |
/// | BilinearSpread  | the slab's whole share of the footprint integral on the 2 x 2 nearest nodes |
///
/// A SlabView is immutable after construction and may be used by many tiles at once.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "pcvr/grid.h"
#include "pcvr/kernel.h"
#include "shaded/sheets/occlusion_map.h"
#include "shaded/sheets/sheet_buffer.h"
#include "shaded/sheets/sheet_geometry.h"
#include "splat/block_linearisation.h"
#include "splat/phase_table.h"
#include "splat/slab_footprint.h"
#include "view/view_projection.h"

namespace pcvr {

/// floor(x) as a sheet index, saturated at +-2^60: sheets that far out are never walked, and a far
/// clip plane at 1e300, or a depth 1e20 sheets out, must not overflow the conversion (NaN: the
/// lowest). Two saturated indices still add up within int64.
inline int64_t sheet_floor(double x) {
    constexpr int64_t kFarthest = int64_t(1) << 60;
    if (!(x > -double(kFarthest))) return -kFarthest;
    if (!(x < double(kFarthest))) return kFarthest;
    return int64_t(std::floor(x));
}

/// The surfaces cutting space into slabs: slab s spans [boundary(s), boundary(s + 1)] of the sheet
/// parameter. Orthographic views: planes (`planes`), of constant depth (camera-space units along the
/// view axis) or, where the metric makes the grids' voxels cubes, perpendicular to the rays there.
/// Perspective views: spheres around the eye (`spherical`) in the sheet metric: the parameter is
/// |metric (x - eye)| (the linear part of `metric`; sheet_geometry.h, sheet_metric), which every ray crosses at right
/// angles where the metric makes voxels cubes, so that a kernel's slabs are the same at every tap of its
/// footprint (planes would cut off-axis kernels at an angle and need each tap's own share).
struct SheetLattice {
    bool spherical = false;
    Vec3 eye;                ///< world position of the eye (spherical)
    Mat4 metric;             ///< world displacement to sheet-parameter space (linear part)
    SheetPlanes planes;      ///< orthographic views: the planes' parameter (sheet_planes)
    double first_depth = 0;  ///< boundary 0: the near clip plane (spherical: its distance on the axis)
    double spacing = 1;      ///< between boundaries
    int64_t count = 0;       ///< slabs up to the far clip plane

    double boundary(int64_t s) const { return first_depth + double(s) * spacing; }
    /// The slab holding depth z (may lie outside [0, count)).
    int64_t slab_of(double z) const { return sheet_floor((z - first_depth) / spacing); }
    /// Where a grid's kernels are round in the metric and the sheets cross its rays at right angles
    /// there (spheres in any metric, planes tilted into the voxels'), the metric length of an index
    /// unit, the same along every ray; else 0.
    double round_scale(const Mat4& index_to_world) const;
};

enum class SlabMode { Footprint, BilinearSpread };

struct SlabBatch;  // eight voxels projected (slab_splat.cpp)

struct SlabSplatParams {
    const Kernel* kernel = nullptr;
    const FootprintTable* table = nullptr;
    const DepthProfile* profile = nullptr;
    int stride = 1;
    SlabMode mode = SlabMode::Footprint;
    float density_scale = 1.0f;
    /// Splat value - background: sheets then hold the departure from the grid's background, which
    /// the walk adds back, so that the reconstruction falls towards the background (not towards 0)
    /// beyond the active voxels, and voxels equal to it cost nothing.
    float background = 0.0f;
};

/// Where a ring lies on its grid's subgrid: ring node (0, 0) is subgrid node (node_x0, node_y0), i.e.
/// image pixel (stride * node_x0, stride * node_y0).
struct RingPlacement {
    int node_x0 = 0, node_y0 = 0;
    Box needed;  ///< the ring nodes the tile reads (the rest only holds whole windows): voxels missing it are skipped
};

struct DepositCounts {
    uint64_t splatted = 0;  ///< voxels that added to at least one sheet node
    uint64_t occluded = 0;  ///< voxels whose window lay wholly on occluded nodes
    uint64_t taps = 0;      ///< node-slab pairs deposited: each window's nodes (within the ring) times its slabs
};

/// The sheet parameter's change over one index unit along the ray through the grid's centre: what
/// "one voxel" of sheet spacing means for this grid (its voxel size along the view direction,
/// anisotropy included): depth for planes, metric length for spheres (the same along every ray
/// where the grid's voxels are cubes in the metric).
double depth_per_voxel(const ViewProjection& projection, const Grid& grid, const SheetLattice& sheets);

class SlabView {
public:
    SlabView(const Grid& grid, const Camera& camera, const SheetLattice& sheets, const SlabSplatParams& params);

    /// Voxels a deposit projects at once (SlabBatch's lanes; DepthOrder is padded to whole batches).
    static constexpr int kBatch = 8;
    /// Sheets one kernel may span (its deposit keeps a pointer and a share per sheet on the stack): enough
    /// for voxels 30 times longer than wide seen along their short side at the default spacing.
    static constexpr int kMostSlabs = 128;
    /// Windows wider than this many nodes take the per-tap path.
    static constexpr int kMostWindow = 16;

    const Grid& grid() const { return *grid_; }
    const ViewProjection& projection() const { return projection_; }
    int stride() const { return params_.stride; }
    /// Sheets a voxel's slabs can reach: ceil(2 reach / spacing) + 1.
    int slabs_per_voxel() const { return slabs_per_voxel_; }
    /// How far a kernel reaches in the sheet parameter from its centre.
    double depth_reach() const { return depth_reach_; }
    /// For the walk's order, which follows planar depth: a voxel of a block whose planar depth is at
    /// least `limit_scale(block) * (sheet parameter)` has at least that sheet parameter (1 for planes;
    /// for spheres the block's largest cosine to the depth axis, in the frame where they are round,
    /// over the sheet parameter per unit of depth along that axis).
    /// And where the block's kernels begin in the sheet parameter.
    double limit_scale(const VoxelBlock& block) const;
    double front(const VoxelBlock& block) const;

    /// A block's voxel offsets in order of depth (structure of arrays, padded to whole batches of
    /// eight with entries that lie beyond every block's voxels).
    struct DepthOrder {
        std::vector<int32_t> offset;
        std::vector<float> i, j, k;  ///< index offsets within the block
        std::vector<float> depth;    ///< depth relative to the block origin's, increasing
    };
    const DepthOrder& depth_order() const { return order_; }
    /// Camera depth of the block's nearest voxel centre (for the clip planes).
    double nearest_depth(const VoxelBlock& block) const;
    /// The block origin's place in the order of DepthOrder::depth: camera depth for spheres, the
    /// sheet parameter for planes.
    double order_depth(const VoxelBlock& block) const;
    /// Voxels to splat (`splat`, or the active ones when null) from rank `first` on (what skipping the
    /// rest of the block leaves out).
    uint64_t voxels_left(const VoxelBlock& block, int first, const VoxelMask* splat = nullptr) const;
    /// Nodes a voxel's window can reach beyond the node its centre falls in, on the far side: rings
    /// this much wider than the nodes a tile reads hold whole windows, which take the fast path.
    int window_margin() const { return window_ ? window_->window() - 1 : 0; }

    /// Splats the active, finite, non-zero voxels of ranks [first, last) of `block` into `ring` at
    /// `placement`, each clipped to the ring. With `occlusion`, voxels whose clipped window lies on
    /// occluded nodes are skipped and counted. Voxels whose kernel reaches the eye plane are skipped
    /// (a perspective footprint does not exist there).
    /// Slabs before `first_open_sheet` (sheets the walk has already composited) are left out, and so
    /// are the voxels not in `splat` when it is given (TileBlock::splat).
    DepositCounts deposit(const VoxelBlock& block, int first, int last, SheetRing& ring, const RingPlacement& placement,
                          int64_t first_open_sheet, const OcclusionMap* occlusion, const VoxelMask* splat = nullptr) const;

    /// Perspective views of kernels round in the sheet metric: models the footprints of these blocks
    /// (indices into the grid's blocks) as affine functions of the voxel (block_linearisation.h), so
    /// that deposits project eight voxels in float instead of each in double. Blocks the model misses
    /// (near the eye) keep the exact projection. Call before rendering; uses every thread.
    void linearise(const std::vector<uint32_t>& blocks);
    /// Blocks linearised (for stats).
    size_t blocks_linearised() const { return linearised_.size(); }

private:
    const BlockLinearisation* linearised(const VoxelBlock& block) const;
    uint32_t place(SlabBatch& b, const SheetRing& ring, const Box& needed, int64_t first_open_sheet) const;
    bool deposit_lane(const SlabBatch& b, int l, SheetRing& ring, const OcclusionMap* occlusion, bool& occluded, Box& reached,
                      int64_t sheets_reached[2], uint64_t& taps) const;

    const Grid* grid_;
    ViewProjection projection_;
    SheetLattice sheets_;
    SlabSplatParams params_;
    int slabs_per_voxel_ = 1;
    double depth_reach_ = 0;
    DepthOrder order_;
    // Orthographic views: node coordinates and depth are affine in index space, the footprint the same for all.
    Vec3 node_gx_, node_gy_;        // subgrid nodes per index step
    double node_x0_ = 0, node_y0_ = 0;  // subgrid node of index (0, 0, 0)
    Footprint shape_;               // in node units (q scaled by stride^2, depth slopes per node)
    // SheetLattice::round_scale: the sheets cross every ray of a kernel at right angles, and every tap
    // shares its slabs (0: they slant, each tap its own share).
    double round_scale_ = 0;
    // Spheres: the frame whose -z is the depth axis, eye at its origin, in which limit_scale measures
    // cosines, and the sheet parameter per unit of z there.
    Mat4 order_frame_;
    double order_scale_ = 1;
    // The order's gradient and offset in index space (DepthOrder, order_depth); planes: the sheet
    // parameter per index length along the rays.
    Vec3 order_gradient_;
    double order_offset_ = 0;
    double plane_kappa_ = 1;
    // linearise(): each listed block's slot in linearised_ (-1: exact projection).
    std::vector<int32_t> linear_slot_;
    std::vector<BlockLinearisation> linearised_;
    std::unique_ptr<PhaseFootprintTable> window_;  // orthographic footprints of a smooth kernel: whole windows
};

}  // namespace pcvr
