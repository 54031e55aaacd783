"""Beyond the paper: splat-kernel / post-filter pairs searched for the best error at PCVR's cost.

A numpy prototype of PCVR's X-ray path for orthographic views (the same camera as the benchmark's
oblique m=4 view): every voxel's footprint (the Abel transform of its radial kernel) is sampled at
its 4 x 4 nearest subgrid nodes (stride L = m, one node per voxel), and the subgrid is post-filtered
to pixels with a separable filter normalised per phase, as native/src/splat/post_convolution.cpp does. Its
(gauss1.4, bilinear) images are checked against the native renderer's (``prototype_check``), so the
other pairs are trusted to the same degree.

| candidate            | splat kernel                                  | post filter                     |
|----------------------|-----------------------------------------------|---------------------------------|
| paper / shipped      | exp(-1.4 r^2), exp(-2.0 r^2)                  | bilinear, Gaussian 1.4 / 2.0    |
| slimmer Gaussians    | exp(-a r^2), a from 2.0 to 6.0, radius 2      | bilinear, cubic B-spline        |
| fitted               | the a whose combined filter (footprint x post | bilinear, cubic B-spline        |
|                      | filter) best matches the gauss1.4 footprint's |                                 |
|                      | response up to 1 cycle per voxel              |                                 |

All candidates splat 16 taps per voxel (same splat cost); bilinear post filters read 2 x 2 nodes per
pixel and the others 4 x 4, so *cost* below is the post filter's taps per axis. Errors are relative
RMSE against ``exact`` (gauss1.4) on every data set and against the analytic X-ray on the blobs.
"""

from __future__ import annotations

import math

import numpy as np

import datasets
import views

GAUSS_A = (1.4, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0)
POSTS = ("bilinear", "bspline3", "gauss1.4", "gauss2.0")
POST_TAPS = {"bilinear": 2, "bspline3": 4, "gauss1.4": 4, "gauss2.0": 4}
RADIUS = 2.0
FIT_MAX_A = 10.0  # narrower than this the 4 x 4 nodes undersample the footprint: the search's bound


def footprint(a: float, rho: np.ndarray) -> np.ndarray:
    """Line integral of exp(-a r^2) truncated at RADIUS, normalised to unit 3-D integral."""
    from scipy.special import erf
    norm = 4.0 * math.pi * (math.sqrt(math.pi) / (4.0 * a ** 1.5) * math.erf(math.sqrt(a) * RADIUS)
                            - RADIUS * math.exp(-a * RADIUS * RADIUS) / (2.0 * a))
    half = np.sqrt(np.clip(RADIUS * RADIUS - rho * rho, 0.0, None))
    return np.where(rho < RADIUS, np.exp(-a * rho * rho) * math.sqrt(math.pi / a) * erf(math.sqrt(a) * half), 0.0) / norm


def post_weight(name: str, t: np.ndarray) -> np.ndarray:
    t = np.abs(t)
    if name == "bilinear":
        return np.clip(1.0 - t, 0.0, None)
    if name == "bspline3":
        return np.where(t < 1.0, 2.0 / 3.0 - t * t + 0.5 * t ** 3, np.where(t < 2.0, (2.0 - t) ** 3 / 6.0, 0.0))
    a = float(name[5:])
    return np.where(t < 2.0, np.exp(-a * t * t), 0.0)


def node_positions(phantom, view):
    """Voxel centres in subgrid node coordinates (x right, y down) and their values, for an
    orthographic view with stride = magnification."""
    w2c, proj = views.matrices(view)
    vals = phantom.values
    idx = np.argwhere(vals != 0)
    v = vals[vals != 0].astype(np.float64)
    world = idx @ phantom.index_to_world[:3, :3].T + phantom.index_to_world[:3, 3]
    clip = (np.c_[world, np.ones(len(world))] @ (proj @ w2c).T)
    px = (clip[:, 0] + 1.0) * 0.5 * view["width"] - 0.5
    py = (1.0 - clip[:, 1]) * 0.5 * view["height"] - 0.5
    stride = int(round(view["magnification"]))
    return px / stride, py / stride, v, stride


def splat_subgrid(nx, ny, v, a, shape):
    """Subgrid of node values: each voxel's footprint at its 4 x 4 nearest nodes (rho in nodes = voxels)."""
    grid = np.zeros(shape)
    bx, by = np.floor(nx).astype(int), np.floor(ny).astype(int)
    for dy in range(-1, 3):
        for dx in range(-1, 3):
            gx, gy = bx + dx, by + dy
            w = footprint(a, np.hypot(gx - nx, gy - ny)) * v
            ok = (gx >= 0) & (gx < shape[1]) & (gy >= 0) & (gy < shape[0])
            np.add.at(grid, (gy[ok], gx[ok]), w[ok])
    return grid


def post_filter(grid, stride, post, width, height):
    """Separable post-convolution from nodes (pixel = stride * node) to pixels, weights normalised per phase."""
    taps = np.arange(-2, 3)

    def along(arr, n_out, axis):
        out_idx = np.arange(n_out)
        base = out_idx // stride
        phase = (out_idx - stride * base) / stride
        w = post_weight(post, phase[:, None] - taps[None, :])
        w /= w.sum(axis=1, keepdims=True)
        nodes = np.clip(base[:, None] + taps[None, :], 0, arr.shape[axis] - 1)
        valid = (base[:, None] + taps[None, :] >= 0) & (base[:, None] + taps[None, :] < arr.shape[axis])
        w = w * valid
        moved = np.moveaxis(arr, axis, 0)
        res = np.einsum("ok,ok...->o...", w, moved[nodes])
        return np.moveaxis(res, 0, axis)

    return along(along(grid, height, 0), width, 1)


def render(phantom, view, a, post, cache=None):
    """The X-ray image in world units (footprints are in index units: times the voxel spacing)."""
    nx, ny, v, stride = cache or node_positions(phantom, view)
    shape = (view["height"] // stride + 3, view["width"] // stride + 3)
    image = post_filter(splat_subgrid(nx, ny, v, a, shape), stride, post, view["width"], view["height"])
    return image * datasets.voxel_spacing(phantom)


def gauss_response_3d(a, freqs):
    """3-D radial Fourier transform of exp(-a r^2) on [0, RADIUS] (the sine transform of figures.hankel
    for n = 3), normalised to 1 at f = 0: by the Fourier slice theorem the footprint's 2-D response."""
    r = np.linspace(0.0, RADIUS, 801)
    h = np.exp(-a * r * r)
    f = np.asarray(freqs, dtype=np.float64)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(f > 0, np.sin(2 * np.pi * f * r) / (2 * np.pi * np.where(f > 0, f, 1.0)), r)
    out = np.trapz(h * r * k, r, axis=1)
    return out / out[0]


def combined_response(a, post, freqs):
    """Radial response of footprint x post filter, averaged over directions (2-D, nodes = voxels)."""
    fp = gauss_response_3d(a, freqs)
    t = np.linspace(-2.0, 2.0, 401)
    w = post_weight(post, t)
    p1 = lambda f: (w[None, :] * np.cos(2 * np.pi * f[:, None] * t[None, :])).sum(axis=1) / w.sum()  # noqa: E731
    angles = np.linspace(0.0, math.pi / 4, 7)
    post2 = np.mean([p1(freqs * math.cos(th)) * p1(freqs * math.sin(th)) for th in angles], axis=0)
    return fp * post2


def fit_width(post: str) -> float:
    """The a of exp(-a r^2) whose combined filter with `post` best matches gauss1.4's footprint
    response (what `exact` renders) over 0..1 cycle per voxel, weighted by the frequency (2-D area)."""
    freqs = np.linspace(0.0, 1.0, 101)
    target = gauss_response_3d(1.4, freqs)
    grid = np.linspace(1.4, FIT_MAX_A, 47)
    costs = [float(np.sum(freqs * (combined_response(a, post, freqs) - target) ** 2)) for a in grid]
    i = int(np.argmin(costs))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    fine = np.linspace(lo, hi, 21)
    costs = [float(np.sum(freqs * (combined_response(a, post, freqs) - target) ** 2)) for a in fine]
    return float(fine[int(np.argmin(costs))])


def shift_variance(phantom, view, a, post) -> float:
    """figures.shift_variance for a prototype pair: the aliasing a slimmer kernel may bring."""
    from figures import shifted
    base = render(phantom, view, a, post)
    errs = []
    for s in range(1, int(round(view["magnification"]))):
        moved = render(phantom, shifted(view, s), a, post)
        errs.append(rel(moved[:, :-s], base[:, s:]))
    return float(np.mean(errs))


def rel(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def run(quick: bool, log) -> dict:
    import pcvr_native as pn
    fitted = {p: round(fit_width(p), 2) for p in ("bilinear", "bspline3")}
    log("kernel search: fitted widths " + ", ".join(f"{p}: a={a:.2f}" for p, a in fitted.items()))
    candidates = sorted({(a, p) for a in GAUSS_A for p in POSTS if p in ("bilinear", "bspline3") or a in (1.4, 2.0)}
                        | {(a, p) for p, a in fitted.items()})
    out = {"fitted": fitted, "candidates": [list(c) for c in candidates], "datasets": {}, "check": {}}
    for ds in datasets.DATASETS:
        ph = ds.phantom(quick)
        view = views.oblique(ph.values.shape, ph.index_to_world, 4)
        cam = views.camera(view)
        grid = ph.grid()
        exact = np.asarray(pn.render_xray(grid, cam, "exact", pixel_step=1 if quick else 3), dtype=np.float64)
        step = 1 if quick else 3
        truth = ds.truth(ph, cam, step, quick)
        cache = node_positions(ph, view)
        native = np.asarray(pn.render_xray(grid, cam, "pcvr", passband="paper"), dtype=np.float64)  # the prototyped pair
        proto = render(ph, view, 1.4, "bilinear", cache)
        out["check"][ds.key] = rel(proto, native)
        rows = {}
        for a, post in candidates:
            img = render(ph, view, a, post, cache)[::step, ::step]
            rows[f"{a:g}|{post}"] = {"vs_exact": rel(img, exact), **({"vs_truth": rel(img, truth)} if truth is not None else {})}
        out["datasets"][ds.key] = {"label": ds.label, "rows": rows}
        if ds.key == "ct":
            out["shift_variance"] = {f"{a:g}|{post}": shift_variance(ph, view, a, post)
                                     for a, post in ((1.4, "bilinear"), (2.0, "bilinear"), (2.5, "bilinear"),
                                                     (3.0, "bilinear"), (1.4, "gauss1.4"))}
            import figures
            out["shift_variance_bilinear_spread"] = figures.shift_variance(grid, view, "bilinear_spread")
        best = min(rows.items(), key=lambda kv: kv[1].get("vs_truth", kv[1]["vs_exact"]))
        log(f"kernel search {ds.key}: prototype vs native {100 * out['check'][ds.key]:.3f}%, best {best[0]} "
            f"{100 * best[1].get('vs_truth', best[1]['vs_exact']):.2f}%")
    return out
