#include "shaded/sheets/slab_splat.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "pcvr/lanes.h"
#include "volume/block_voxels.h"

namespace pcvr {


namespace {

// SlabView's limits (slab_splat.h), which its preparation (slab_view.cpp) checks too.
constexpr int kBatch = SlabView::kBatch;
constexpr int kMostSlabs = SlabView::kMostSlabs;
constexpr int kMostWindow = SlabView::kMostWindow;

inline void add8(float* p, float8 v) { store8(p, load8(p) + v); }

typedef float float4 __attribute__((vector_size(16)));
inline float4 low4(float8 v) { return float4{v[0], v[1], v[2], v[3]}; }
inline float4 high4(float8 v) { return float4{v[4], v[5], v[6], v[7]}; }
inline void add4(float* p, float4 v) {
    float4 x;
    std::memcpy(&x, p, sizeof x);
    x += v;
    std::memcpy(p, &x, sizeof x);
}

/// An outermost slab share below this joins the slab beside it (deposit_lane): 1% of a voxel's value
/// moved by at most a sheet. Measured on the CT head at 512^2: 25% fewer taps, PSNR against the ray
/// caster 41.11 -> 41.11 dB (translucent), 36.59 -> 36.95 dB (bone).
constexpr float kTail = 0.01f;

/// Voxel values of ranks [first, first + 8) less the background: 0 for ranks at or past `last`, for
/// voxels not in `mask` (unless `full`: every voxel is in it) and non-finite ones.
float8 batch_values(const VoxelBlock& block, const SlabView::DepthOrder& order, int first, int last, bool full, const VoxelMask& mask,
                    float background) {
    float8 v;
    if (full && last - first >= kBatch) {
        // Every rank a voxel: gather them (the order's offsets are valid past the block's end too).
        int8x offsets;
        std::memcpy(&offsets, order.offset.data() + first, sizeof offsets);
        v = (block.values ? gather8(block.values, offsets) : broadcast8(block.constant)) - background;
    } else {
        for (int l = 0; l < kBatch; ++l) {
            const int rank = first + l;
            const int offset = order.offset[rank];
            v[l] = rank < last && (full || contains(mask, offset)) ? block.value(offset) - background : 0.0f;
        }
    }
    return select8(abs8(v) < INFINITY, v, broadcast8(0.0f));  // NaN and infinity: skipped, not splatted
}

uint32_t non_zero_lanes(float8 v) { return lane_mask(v != 0.0f); }

/// floor of eight floats within int's range (truncation, less one where it rounded up).
int8x floor_to_int8(float8 x) {
    const int8x t = __builtin_convertvector(x, int8x);
    return t + (__builtin_convertvector(t, float8) > x);  // a true comparison is -1
}
int8x ceil_to_int8(float8 x) { return -floor_to_int8(-x); }
int8x max8i(int8x a, int8x b) { return a > b ? a : b; }
int8x min8i(int8x a, int8x b) { return a < b ? a : b; }
void store8i(int32_t* p, int8x v) { std::memcpy(p, &v, sizeof v); }
int8x load8i(const int32_t* p) {
    int8x v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
int8x lane_bits8(uint32_t mask) { return (int8x{1, 2, 4, 8, 16, 32, 64, 128} & int(mask)) != 0; }

}  // namespace

/// Eight voxels projected onto a ring: everything the deposit needs, per lane, in ring node units.
struct SlabBatch {
    float cx[kBatch], cy[kBatch];                // centre
    float qxx[kBatch], qxy[kBatch], qyy[kBatch];  // rho^2 per node offset
    float ext_x[kBatch], ext_y[kBatch];          // half-widths of the ellipse's bounding box
    float amp[kBatch];                           // value * density scale * sheet parameter per index length along the ray
    float s0[kBatch];                            // s (index units along the ray) of the first slab's front, at the centre
    float s_dx[kBatch], s_dy[kBatch];            // change of s per node offset
    float s_step[kBatch];                        // s between consecutive slab boundaries
    int64_t first_sheet[kBatch];
    uint32_t live = 0;                           // lanes holding a voxel to splat
    uint32_t aligned = 0;                        // lanes whose slab shares hold at every tap
    float share[kMostSlabs][kBatch];             // each slab's share of the footprint, at the centre
    // Set by place(): each lane's window of ring nodes (corner first), the part of it on the ring, and
    // the slabs [first_slab, end_slab) it deposits (tails merged).
    int32_t x0[kBatch], y0[kBatch], x1[kBatch], y1[kBatch];
    int32_t on_x0[kBatch], on_y0[kBatch], on_x1[kBatch], on_y1[kBatch];
    int32_t first_slab[kBatch], end_slab[kBatch];
};

// Beside the deposit, which inlines these once a call (the view's other queries are in slab_view.cpp).
const BlockLinearisation* SlabView::linearised(const VoxelBlock& block) const {
    if (linearised_.empty()) return nullptr;
    const int32_t slot = linear_slot_[size_t(&block - grid_->blocks().data())];
    return slot < 0 ? nullptr : &linearised_[size_t(slot)];
}

double SlabView::order_depth(const VoxelBlock& block) const {
    return dot(order_gradient_, Vec3{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])}) + order_offset_;
}

namespace {

/// What one voxel's deposit needs besides its projection: its slabs, the ring sheets they land in and
/// each slab's share of the footprint at the centre (the whole footprint when `aligned`).
struct LaneSlabs {
    int first, count;            // slabs [first, count) of the voxel go into sheets[first..]
    float* sheets[kMostSlabs];
    float share[kMostSlabs];
    bool aligned;                // the shares hold at every tap
};

/// Footprint weights (times amplitude) of eight taps at node offsets (dx, dy) from the centre, added to
/// `row` of every slab's sheet: with the slab shares, or with D evaluated at each tap.
template <class Add>
inline void add_taps(const SlabBatch& b, int l, const DepthProfile& depth, const LaneSlabs& slabs, size_t row, float8 weight,
                     float8 dx, float8 dy, Add add) {
    if (slabs.aligned) {
        for (int k = slabs.first; k < slabs.count; ++k) add(slabs.sheets[k] + row, weight * slabs.share[k]);
        return;
    }
    const auto clamp_unit = [](float8 t) { return clamp8(t, -1.0f, 1.0f); };
    const auto magnitude = [](float8 t) { return abs8(t); };
    const float radius = depth.radius();
    // Before the kernel's reach D is 0 and beyond it 1: slabs wholly outside take no polynomial, and
    // once every tap is past the kernel the rest of the slabs get nothing.
    auto D = [&](float8 s) {
        if (!any8(s > -radius)) return broadcast8(0.0f);
        if (!any8(s < radius)) return broadcast8(1.0f);
        return depth(s, clamp_unit, magnitude);
    };
    float8 s = b.s0[l] + slabs.first * b.s_step[l] + b.s_dx[l] * dx + b.s_dy[l] * dy;
    float8 front = D(s);
    for (int k = slabs.first; k < slabs.count; ++k) {
        s += b.s_step[l];
        const float8 back = D(s);
        if (any8(back != front)) add(slabs.sheets[k] + row, weight * (back - front));
        if (!any8(s < radius)) break;
        front = back;
    }
}

/// The footprint's taps row by row over `window` (ring nodes), eight at a time, weights from the
/// footprint table (FootprintTable::weights): any footprint (perspective, box kernel, wide windows).
void deposit_footprint(const SlabBatch& b, int l, const FootprintTable& table, const DepthProfile& depth,
                       const LaneSlabs& slabs, const Box& window, size_t pitch) {
    const float cx = b.cx[l], cy = b.cy[l];
    const float qxx = b.qxx[l], qxy2 = 2.0f * b.qxy[l], qyy = b.qyy[l];
    const float8 lanes = lane_index8();
    for (int r = window.y0; r <= window.y1; ++r) {
        const float dy = float(r) - cy;
        for (int col = window.x0; col <= window.x1; col += kBatch) {
            const float8 dx = (float(col) - cx) + lanes;
            const int8x inside = lanes <= float(window.x1 - col);
            const float8 rho2 = (qxx * dx + qxy2 * dy) * dx + qyy * dy * dy;
            const float8 weight = select8(inside, table.weights(rho2) * b.amp[l], broadcast8(0.0f));
            add_taps(b, l, depth, slabs, size_t(r) * pitch + col, weight, dx, broadcast8(dy), add8);
        }
    }
}

/// An orthographic footprint's whole window from the phase table, its corner at ring node (col, row)
/// and wholly inside the ring: no lookups per tap. PCVR's 4 x 4 window goes two rows per vector.
void deposit_window(const SlabBatch& b, int l, const PhaseFootprintTable& table, const DepthProfile& depth,
                    const LaneSlabs& slabs, int col, int row, size_t pitch) {
    const float cx = b.cx[l], cy = b.cy[l];
    const PhaseFootprintTable::Blend blend = table.blend(cx - std::floor(cx), cy - std::floor(cy));
    const float amp = b.amp[l];
    const float8 c0 = broadcast8(blend.coeff[0] * amp), c1 = broadcast8(blend.coeff[1] * amp);
    const float8 c2 = broadcast8(blend.coeff[2] * amp), c3 = broadcast8(blend.coeff[3] * amp);
    auto weights = [&](size_t t) {
        return c0 * load8(blend.entry[0] + t) + c1 * load8(blend.entry[1] + t) + c2 * load8(blend.entry[2] + t) +
               c3 * load8(blend.entry[3] + t);
    };
    const float8 lanes = lane_index8();
    if (table.window() == 4) {
        // Lanes 0-3: taps of one row, 4-7: of the next; each half goes into its own ring row.
        const float8 column = (float(col) - cx) + select8(lanes < 4.0f, lanes, lanes - 4.0f);
        const float8 half = select8(lanes < 4.0f, broadcast8(0.0f), broadcast8(1.0f));
        for (int pair = 0; pair < 2; ++pair) {
            const float8 dy = (float(row + 2 * pair) - cy) + half;
            const size_t at = size_t(row + 2 * pair) * pitch + col;
            add_taps(b, l, depth, slabs, at, weights(size_t(8 * pair)), column, dy, [pitch](float* p, float8 w) {
                add4(p, low4(w));
                add4(p + pitch, high4(w));
            });
        }
        return;
    }
    const int window = table.window(), row_floats = table.pitch();
    for (int j = 0; j < window; ++j) {
        const float8 dy = broadcast8(float(row + j) - cy);
        for (int i = 0; i < row_floats; i += kBatch)
            add_taps(b, l, depth, slabs, size_t(row + j) * pitch + col + i, weights(size_t(j) * row_floats + i),
                     (float(col + i) - cx) + lanes, dy, add8);
    }
}

/// Westenberg-Roerdink: each slab's share of the footprint integral on the 2 x 2 nodes around the
/// centre (corner (col, row)), clipped to `window`.
void deposit_spread(const SlabBatch& b, int l, const LaneSlabs& slabs, int col, int row, const Box& window, size_t pitch) {
    const float fx = b.cx[l] - float(col), fy = b.cy[l] - float(row);
    const float w[2][2] = {{(1 - fx) * (1 - fy), fx * (1 - fy)}, {(1 - fx) * fy, fx * fy}};
    for (int k = slabs.first; k < slabs.count; ++k) {
        const float mass = b.amp[l] * slabs.share[k];
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i)
                if (col + i >= window.x0 && col + i <= window.x1 && row + j >= window.y0 && row + j <= window.y1)
                    slabs.sheets[k][size_t(row + j) * pitch + col + i] += mass * w[j][i];
    }
}

}  // namespace

/// Each lane's window, the part of it on the ring and its slabs, eight lanes at once (what a voxel's
/// deposit did lane by lane had cost about a quarter of the splat at 1-2 pixels per voxel). Returns
/// the live lanes whose window meets the ring where the walk needs it.
uint32_t SlabView::place(SlabBatch& b, const SheetRing& ring, const Box& needed, int64_t first_open_sheet) const {
    const float8 cx = load8(b.cx), cy = load8(b.cy);
    const float columns = float(ring.columns()), rows = float(ring.rows());
    int8x x0, y0, x1, y1;
    if (params_.mode == SlabMode::BilinearSpread) {  // the 2 x 2 nodes around the centre
        x0 = floor_to_int8(clamp8(cx, -2.0f, columns)), y0 = floor_to_int8(clamp8(cy, -2.0f, rows));
        x1 = x0 + 1, y1 = y0 + 1;
    } else if (window_) {  // the phase table's window
        const float far = float(kMostWindow);
        const int h = window_->half_width(), w = window_->window();
        x0 = floor_to_int8(clamp8(cx, -far, columns + far)) - h + 1, y0 = floor_to_int8(clamp8(cy, -far, rows + far)) - h + 1;
        x1 = x0 + (w - 1), y1 = y0 + (w - 1);
    } else {  // the ellipse's bounding box
        const float8 ex = load8(b.ext_x), ey = load8(b.ext_y);
        x0 = ceil_to_int8(clamp8(cx - ex, -1.0f, columns)), x1 = floor_to_int8(clamp8(cx + ex, -1.0f, columns));
        y0 = ceil_to_int8(clamp8(cy - ey, -1.0f, rows)), y1 = floor_to_int8(clamp8(cy + ey, -1.0f, rows));
    }
    const int8x on_x0 = max8i(x0, int8x{} + 0), on_x1 = min8i(x1, int8x{} + (ring.columns() - 1));
    const int8x on_y0 = max8i(y0, int8x{} + 0), on_y1 = min8i(y1, int8x{} + (ring.rows() - 1));
    const int8x meets = (on_x0 <= on_x1) & (on_y0 <= on_y1) & (max8i(x0, int8x{} + needed.x0) <= min8i(x1, int8x{} + needed.x1)) &
                        (max8i(y0, int8x{} + needed.y0) <= min8i(y1, int8x{} + needed.y1));
    store8i(b.x0, x0), store8i(b.y0, y0), store8i(b.x1, x1), store8i(b.y1, y1);
    store8i(b.on_x0, on_x0), store8i(b.on_y0, on_y0), store8i(b.on_x1, on_x1), store8i(b.on_y1, on_y1);

    // The slabs still open; a kernel's outermost slabs often hold only its tail: a share below kTail
    // goes into the slab beside it (a sheet deeper or shallower; the slabs still sum to the footprint)
    // and costs no taps. A quarter of the taps on the CT head, at the same PSNR against the ray caster.
    const int n = slabs_per_voxel_;
    for (int l = 0; l < kBatch; ++l)  // (dead lanes' sheets may be unset)
        b.first_slab[l] = (b.live >> l) & 1 ? int32_t(std::clamp<int64_t>(first_open_sheet - b.first_sheet[l], 0, n)) : n;
    int8x first = load8i(b.first_slab), end = int8x{} + n;
    const int8x aligned = lane_bits8(b.aligned);
    for (int k = 0; k + 1 < n; ++k) {
        const float8 share = load8(b.share[k]);
        const int8x merge = aligned & (first == k) & (end - first > 1) & (abs8(share) < kTail);
        if (!any8(merge)) continue;
        store8(b.share[k + 1], load8(b.share[k + 1]) + select8(merge, share, broadcast8(0.0f)));
        first -= merge;  // a true comparison is -1
    }
    for (int k = n - 1; k > 0; --k) {
        const float8 share = load8(b.share[k]);
        const int8x merge = aligned & (end - 1 == k) & (end - first > 1) & (abs8(share) < kTail);
        if (!any8(merge)) continue;
        store8(b.share[k - 1], load8(b.share[k - 1]) + select8(merge, share, broadcast8(0.0f)));
        end += merge;
    }
    store8i(b.first_slab, first), store8i(b.end_slab, end);
    return b.live & lane_mask(meets);
}

/// The slab footprints of one placed voxel (lane l of `b`) added into `ring`. Returns false when its
/// window lies on occluded nodes (then `occluded` is set) or its slabs are closed.
bool SlabView::deposit_lane(const SlabBatch& b, int l, SheetRing& ring, const OcclusionMap* occlusion, bool& occluded, Box& reached,
                            int64_t sheets_reached[2], uint64_t& taps) const {
    const Box on_ring{b.on_x0[l], b.on_y0[l], b.on_x1[l], b.on_y1[l]};
    if (occlusion && occlusion->covered(on_ring)) {
        occluded = true;
        return false;
    }
    LaneSlabs slabs;
    slabs.first = b.first_slab[l], slabs.count = b.end_slab[l];
    if (slabs.first >= slabs.count) return false;
    const int64_t first_sheet = b.first_sheet[l];
    for (int k = slabs.first; k < slabs.count; ++k) {
        slabs.sheets[k] = ring.sheet(first_sheet + k);
        slabs.share[k] = b.share[k][l];
    }
    slabs.aligned = (b.aligned >> l) & 1;
    reached.include(on_ring);
    sheets_reached[0] = std::min(sheets_reached[0], first_sheet + slabs.first);
    sheets_reached[1] = std::max(sheets_reached[1], first_sheet + slabs.count - 1);

    taps += uint64_t(on_ring.x1 - on_ring.x0 + 1) * uint64_t(on_ring.y1 - on_ring.y0 + 1) * uint64_t(slabs.count - slabs.first);
    const size_t pitch = ring.pitch();
    const Box window{b.x0[l], b.y0[l], b.x1[l], b.y1[l]};
    if (params_.mode == SlabMode::BilinearSpread)
        deposit_spread(b, l, slabs, window.x0, window.y0, on_ring, pitch);
    else if (window_ && on_ring.x0 == window.x0 && on_ring.y0 == window.y0 && on_ring.x1 == window.x1 && on_ring.y1 == window.y1)
        deposit_window(b, l, *window_, *params_.profile, slabs, window.x0, window.y0, pitch);
    else
        deposit_footprint(b, l, *params_.table, *params_.profile, slabs, on_ring, pitch);
    return true;
}


DepositCounts SlabView::deposit(const VoxelBlock& block, int first, int last, SheetRing& ring, const RingPlacement& placement,
                                int64_t first_open_sheet, const OcclusionMap* occlusion, const VoxelMask* splat) const {
    DepositCounts counts;
    if (first >= last) return counts;
    const bool full = !splat && all_active(block);
    const VoxelMask& mask = splat ? *splat : block.mask;
    const double stride = params_.stride, inv_stride = 1.0 / stride;
    const double spacing = sheets_.spacing, inv_spacing = 1.0 / spacing;
    const Vec3 origin{double(block.origin[0]), double(block.origin[1]), double(block.origin[2])};
    // Perspective blocks with a model (linearise): their voxels' metric distances from the eye are taken
    // relative to the origin's, o its offset from the eye in index units.
    const BlockLinearisation* lin = projection_.orthographic() ? nullptr : linearised(block);
    const Vec3 o = origin - projection_.eye();
    // Sheet parameters relative to the slab holding the block origin's (planes: its depth; modelled
    // blocks: its distance) keep the per-voxel arithmetic in small floats.
    const double origin_slabs = ((lin ? round_scale_ * length(o) : order_depth(block)) - sheets_.first_depth) * inv_spacing;
    const int64_t base_sheet = sheet_floor(origin_slabs);
    const float base_fraction = float(origin_slabs - double(base_sheet));
    const float reach_slabs = float(depth_reach_ * inv_spacing);
    const bool spread = params_.mode == SlabMode::BilinearSpread;
    const float density_scale = params_.density_scale;
    const DepthProfile& profile = *params_.profile;
    auto D = [&profile](float8 s) {
        return profile(s, [](float8 t) { return clamp8(t, -1.0f, 1.0f); }, [](float8 t) { return abs8(t); });
    };

    SlabBatch b;
    for (int batch = first; batch < last; batch += kBatch) {
        const float8 v = batch_values(block, order_, batch, last, full, mask, params_.background);
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
            const float kappa = float(plane_kappa_);
            for (int l = 0; l < kBatch; ++l) {
                // Lanes past the block's last voxel lie at infinite depth (DepthOrder's padding) and
                // splat nothing: their sheet is not converted from infinity.
                const float front = b.live & (1u << l) ? std::floor(centre[l] - reach_slabs) : 0.0f;
                b.cx[l] = cx[l];
                b.cy[l] = cy[l];
                b.first_sheet[l] = base_sheet + sheet_floor(front);
                b.s0[l] = (front - centre[l]) * float(spacing) / kappa;
            }
            const double det = shape_.qxx * shape_.qyy - shape_.qxy * shape_.qxy;
            const float ext_x = float(params_.kernel->radius() * std::sqrt(shape_.qyy / det));
            const float ext_y = float(params_.kernel->radius() * std::sqrt(shape_.qxx / det));
            const float amp_per_value = float(density_scale * kappa * (spread ? 1.0 / std::sqrt(det) : 1.0));
            for (int l = 0; l < kBatch; ++l) {
                b.qxx[l] = float(shape_.qxx);
                b.qxy[l] = float(shape_.qxy);
                b.qyy[l] = float(shape_.qyy);
                b.ext_x[l] = ext_x;
                b.ext_y[l] = ext_y;
                b.amp[l] = v[l] * amp_per_value;
                // Tilted planes cross every ray of a round kernel at the centre's place along it.
                b.s_dx[l] = round_scale_ > 0 ? 0.0f : float(-shape_.depth_dx / shape_.depth_per_index);
                b.s_dy[l] = round_scale_ > 0 ? 0.0f : float(-shape_.depth_dy / shape_.depth_per_index);
                b.s_step[l] = float(spacing / kappa);
            }
        } else if (lin) {
            // Round kernels in a linearised block: centres exact as ratios of affine functions, forms
            // from the block's model, the metric distance from the eye relative to the origin's (in
            // float: |o + d| - |o| = (2 o.d + d.d) / (|o + d| + |o|)).
            const float8 i = load8(order_.i.data() + batch), j = load8(order_.j.data() + batch), k = load8(order_.k.data() + batch);
            auto at = [&](const AffineInBlock& f) { return f.at + f.di * i + f.dj * j + f.dk * k; };
            const float8 w = at(lin->w);
            store8(b.cx, at(lin->x) / w - float(placement.node_x0));
            store8(b.cy, at(lin->y) / w - float(placement.node_y0));
            const float8 qxx = at(lin->qxx), qxy = at(lin->qxy), qyy = at(lin->qyy), det = qxx * qyy - qxy * qxy;
            store8(b.qxx, qxx);
            store8(b.qxy, qxy);
            store8(b.qyy, qyy);
            const float radius = float(params_.kernel->radius());
            store8(b.ext_x, sqrt8(qyy / det) * radius);
            store8(b.ext_y, sqrt8(qxx / det) * radius);
            store8(b.amp, v * float(density_scale * round_scale_));
            const float ox = float(o.x), oy = float(o.y), oz = float(o.z), o_length = float(length(o));
            const float8 px = i + ox, py = j + oy, pz = k + oz;
            const float8 further = (2.0f * (ox * i + oy * j + oz * k) + i * i + j * j + k * k) / (sqrt8(px * px + py * py + pz * pz) + o_length);
            const float8 centre = base_fraction + further * float(round_scale_ * inv_spacing);
            const float step_index = float(spacing / round_scale_);
            for (int l = 0; l < kBatch; ++l) {
                const float front = std::floor(centre[l] - reach_slabs);
                b.first_sheet[l] = base_sheet + int64_t(front);
                b.s0[l] = (front - centre[l]) * step_index;
                b.s_dx[l] = b.s_dy[l] = 0.0f;
                b.s_step[l] = step_index;
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
                // Node units, and the sheet parameter: spheres take the metric distance from the eye,
                // which the ray through the centre covers at kappa per index length. Where the grid's
                // voxels are cubes in the metric that is its round scale on every ray, and the closest
                // approach of every ray of the footprint lies at the centre's distance (to second
                // order): every tap shares the centre's slabs. World spheres (the metric is the world's)
                // cut anisotropic kernels at an angle: the distance moves across the footprint.
                const double s2 = stride * stride;
                const double4 qxx = f.qxx * s2, qxy = f.qxy * s2, qyy = f.qyy * s2, det = qxx * qyy - qxy * qxy;
                double4 kappa = f.depth_per_index, parameter = f.depth, distance_dx = f.depth_dx, distance_dy = f.depth_dy;
                if (round_scale_ > 0) {
                    const Vec3& eye = projection_.eye();
                    const double4 ex = x - eye.x, ey = y - eye.y, ez = z - eye.z;
                    kappa = double4{} + round_scale_;
                    parameter = sqrt4(ex * ex + ey * ey + ez * ez) * round_scale_;
                    distance_dx = distance_dy = double4{};
                } else if (sheets_.spherical) {
                    const Mat4& w = grid_->index_to_world();
                    auto offset = [&](int r) { return x * w.m[r][0] + y * w.m[r][1] + z * w.m[r][2] + (w.m[r][3] - sheets_.eye[r]); };
                    const double4 ex = offset(0), ey = offset(1), ez = offset(2);
                    kappa = f.line_scale;
                    parameter = sqrt4(ex * ex + ey * ey + ez * ez);
                    distance_dx = f.distance_dx, distance_dy = f.distance_dy;
                }
                const double radius = params_.kernel->radius();
                const double4 ext_x = sqrt4(qyy / det) * radius, ext_y = sqrt4(qxx / det) * radius;
                const double4 slabs = (parameter - sheets_.first_depth) * inv_spacing;
                const double4 step = spacing / kappa;
                for (int l = 0; l < 4; ++l) {
                    const int lane = 4 * half + l;
                    // A footprint needs the whole kernel in front of the eye.
                    if (!(clip_w[l] > 0) || !(f.depth[l] > depth_reach_)) {
                        b.live &= ~(1u << lane);
                        continue;
                    }
                    const double front = std::floor(slabs[l] - depth_reach_ * inv_spacing);
                    b.cx[lane] = float(f.px[l] * inv_stride - placement.node_x0);
                    b.cy[lane] = float(f.py[l] * inv_stride - placement.node_y0);
                    b.qxx[lane] = float(qxx[l]);
                    b.qxy[lane] = float(qxy[l]);
                    b.qyy[lane] = float(qyy[l]);
                    b.ext_x[lane] = float(ext_x[l]);
                    b.ext_y[lane] = float(ext_y[l]);
                    b.amp[lane] = float(v[lane] * density_scale * kappa[l] * (spread ? 1.0 / std::sqrt(det[l]) : 1.0));
                    b.first_sheet[lane] = sheet_floor(front);
                    b.s0[lane] = float((front - slabs[l]) * step[l]);
                    b.s_dx[lane] = float(-distance_dx[l] * stride / kappa[l]);
                    b.s_dy[lane] = float(-distance_dy[l] * stride / kappa[l]);
                    b.s_step[lane] = float(step[l]);
                }
            }
        }
        // Each slab's share of the footprint at the centre, eight voxels at once; sheets perpendicular to
        // the rays through the kernel (isotropic voxels, orthographic view) give every tap that share.
        // Aligned means that s moves by less than 1e-4 index units across the footprint (D changes by
        // less than 1e-4 there); spreading puts each slab's share at the centre anyway.
        const float8 s0 = load8(b.s0), step = load8(b.s_step);
        float8 front = D(s0);
        for (int k = 0; k < slabs_per_voxel_; ++k) {
            const float8 back = D(s0 + float(k + 1) * step);
            store8(b.share[k], back - front);
            front = back;
        }
        const int8x aligned = abs8(load8(b.s_dx)) * load8(b.ext_x) + abs8(load8(b.s_dy)) * load8(b.ext_y) < 1e-4f;
        b.aligned = spread ? 0xffu : lane_mask(aligned);

        Box reached;
        int64_t sheets_reached[2] = {INT64_MAX, INT64_MIN};
        for (uint32_t todo = place(b, ring, placement.needed, first_open_sheet); todo; todo &= todo - 1) {
            const int l = __builtin_ctz(todo);
            bool occluded = false;
            if (deposit_lane(b, l, ring, occlusion, occluded, reached, sheets_reached, counts.taps))
                ++counts.splatted;
            else if (occluded)
                ++counts.occluded;
        }
        // What the batch reached, once per sheet: boxes only need to bound where sheets are not zero.
        for (int64_t sheet = sheets_reached[0]; sheet <= sheets_reached[1]; ++sheet) ring.touch(sheet, reached);
    }
    return counts;
}

}  // namespace pcvr
