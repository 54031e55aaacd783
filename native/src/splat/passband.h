/// @file passband.h
/// @brief Passband compensation: a small sharpening of the splat grid that pays back the blur of the
/// splat kernel and the post filter, so that images approach the line integrals of the sampled signal.
///
/// By the Fourier slice theorem a filter of the volume is a filter of its X-ray, and a discrete filter of
/// the voxels is one with taps a voxel apart in the image. The nodes of an X-ray's splat grid are a
/// projected voxel spacing apart, so the filter [-a, 1 + 2a, -a] along each axis of the grid (weights a
/// node apart) stands for it. It sums to one (constants and mass stay) and adds -2a nodes^2 of variance
/// along each axis, so a = blur / 2 takes back a blur of that variance to second order. Its response
/// 1 + 2a (1 - cos 2 pi f) is periodic in the node frequency f, back at 1 on the replicas at whole
/// frequencies: the lattice ripple of the kernel and the subgrid's aliasing grow no more than the passband
/// (a continuous sharpening, the kernel minus a times its Laplacian, would multiply the ripple by
/// 1 + 4 pi^2 a: eightfold for gauss1.4).
///
/// | blur paid back (nodes^2)           | pcvr                                   | regular                  |
/// |------------------------------------|----------------------------------------|--------------------------|
/// | kernel (Kernel::variance, voxels^2)| times (voxel spacing / node spacing)^2 | likewise, taps d px apart |
/// | post filter (post_filter_blur)     | its mean over the pixels               | none                     |
///
/// Regular splatting's grid is the image: its taps are d = round(magnification) pixels apart (whole, so
/// no interpolation), about a voxel. Bilinear spreading and `exact` keep the paper's passband.
#pragma once

#include "pcvr/render_control.h"
#include "splat/splat_grid.h"

namespace pcvr {

/// The share of the blur the compensation takes back: 1 is the second-order match, and a little more pays
/// back some of the fourth-order rest. Chosen by the mean relative RMS error of pcvr and regular against
/// the analytic line integrals of two volumes of Gaussian blobs (sigma 1.2-4 and 1.5-4 voxels) over
/// magnifications 1-4 and three sub-voxel camera offsets: 0.55% at 1.0, 0.49% at 1.1, 0.58% at 1.2,
/// 1.2% at 1.5 (the paper's pair: 3.1%); tests/bench/passband_bench.py measures it.
constexpr double kPassbandStrength = 1.1;

/// The weight a of [-a, 1 + 2a, -a] that takes back `blur` nodes^2 of variance per axis.
double passband_sharpening(double blur);

/// Each node becomes (1 + 2a) itself minus a times the nodes `distance` away along each axis, rows then
/// columns (outside the grid counts as zero). Values spread `distance` nodes: at most one tile
/// (SplatGrid::kTile), which post_convolve's reach covers, so no tile flags change.
void sharpen_nodes(SplatGrid& grid, double a, int distance, RenderControl& control);

}  // namespace pcvr
