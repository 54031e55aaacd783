#include "shaded/light/penumbra.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace pcvr {

namespace {

/// Sums over rectangles of one slice in constant time: table[(r + 1) (nu + 1) + c + 1] holds the sum over
/// rows [0, r] and columns [0, c].
class SummedArea {
public:
    SummedArea(int nu, int nv) : nu_(nu), nv_(nv), table_(size_t(nu + 1) * (nv + 1), 0.0) {}
    template <class Value>
    void fill(Value value) {
        for (int r = 0; r < nv_; ++r)
            for (int c = 0; c < nu_; ++c)
                table_[at(r + 1, c + 1)] = value(r, c) + table_[at(r, c + 1)] + table_[at(r + 1, c)] - table_[at(r, c)];
    }
    /// The sum over the square of half-width `half` texels around (r, c), clipped to the slice, and its texels.
    double sum(int r, int c, int half, int& count) const {
        const int r0 = std::max(0, r - half), r1 = std::min(nv_ - 1, r + half);
        const int c0 = std::max(0, c - half), c1 = std::min(nu_ - 1, c + half);
        count = (r1 - r0 + 1) * (c1 - c0 + 1);
        return table_[at(r1 + 1, c1 + 1)] - table_[at(r0, c1 + 1)] - table_[at(r1 + 1, c0)] + table_[at(r0, c0)];
    }

private:
    size_t at(int r, int c) const { return size_t(r) * (nu_ + 1) + c; }
    int nu_, nv_;
    std::vector<double> table_;
};

/// Half-widths in texels, at most the slice's size (a sun far wider than the volumes).
int texels_within(float distance, float du, int most) {
    return int(std::lround(std::clamp(double(distance) / du, 0.0, double(most))));
}

}  // namespace

void soften_penumbrae(uint16_t* transmittance, const float* depth, const float* occluder, const SunLattice& l,
                      float spread, float whole, RenderControl& control) {
    const int most = std::max(l.nu, l.nv);
    auto texel = [&](int iv, int iw, int iu) { return (size_t(iv) * l.nw + iw) * l.nu + iu; };
    // Every slice's transmittance summed, before any is softened: the occluders' light is read nearer to them.
    std::vector<SummedArea> light(size_t(l.nw), SummedArea(l.nu, l.nv));
    tbb::parallel_for(0, l.nw, [&](int iw) {
        light[size_t(iw)].fill([&](int r, int c) { return double(transmittance[texel(r, iw, c)]); });
    });
    control.throw_if_cancelled();
    tbb::parallel_for(0, l.nw, [&](int iw) {
        control.throw_if_cancelled();
        const float w = l.w0 + iw * l.dw;
        const int search = texels_within((w - l.w0) * spread, l.du, most);
        if (search < 1) return;  // no penumbra a texel wide yet
        SummedArea tau(l.nu, l.nv), tau_depth(l.nu, l.nv);
        tau.fill([&](int r, int c) { return double(depth[texel(r, iw, c)]); });
        tau_depth.fill([&](int r, int c) { return double(depth[texel(r, iw, c)]) * occluder[texel(r, iw, c)]; });
        for (int r = 0; r < l.nv; ++r)
            for (int c = 0; c < l.nu; ++c) {
                int n = 0;
                const double occluding = tau.sum(r, c, search, n);
                if (!(occluding > 1e-6)) continue;  // nothing near enough to cover any of the disc
                const double occluder_depth = tau_depth.sum(r, c, search, n) / occluding;
                // The square of 2 half + 1 texels as large as the disc: (2 half + 1)^2 = pi radius^2.
                const float radius = float(w - occluder_depth) * spread / l.du;
                const int half = int(std::lround(std::clamp((1.7724539f * radius - 1.0f) * 0.5f, 0.0f, float(most))));
                if (half < 1) continue;
                // The light that passes the occluders, averaged over the disc where they cut the cone (at the
                // slice midway to them), times what the texel's own surroundings take from it on the rest of
                // the way: a receiver's self-shadow is not blurred by its neighbours' columns.
                const int split = std::clamp(int(std::lround((0.5 * (occluder_depth + w) - l.w0) / l.dw)), 0, iw);
                const double passed = light[size_t(split)].sum(r, c, half, n) / n;
                const double own = std::exp(-double(depth[texel(r, iw, c)] - depth[texel(r, split, c)]));
                transmittance[texel(r, iw, c)] = uint16_t(std::lround(std::clamp(passed * own, 0.0, double(whole))));
            }
    });
}

}  // namespace pcvr
