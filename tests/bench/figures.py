"""The paper's analysis as generated figures (docs/figures/*.png) and the numbers that go with them.

| figure                     | paper      | what                                                                      |
|----------------------------|------------|---------------------------------------------------------------------------|
| frequency_responses.png    | Figs 4-6   | radial frequency responses of box, linear and Gaussian kernels in 1, 2, 3 |
|                            |            | dimensions (Hankel transform), replica distances 1, sqrt 2, sqrt 3 marked; |
|                            |            | 2-D maps of the linear and Gaussian responses over the replica lattice    |
| combined_filters.png       | Fig 7      | splat kernel x post filter, along an image axis and the diagonal, and     |
|                            |            | with the passband compensation (dashed)                                   |
| ct_comparison.png          | Figs 11/12 | CT phantom: regular, PCVR bilinear / Gaussian post, bilinear spreading,    |
|                            |            | the subgrid before post-convolution, amplified differences               |
| bilinear_aliasing.png      | Fig 12 i/k | bilinear spreading at m = 1..4 next to Gaussian splatting at 4, and the   |
|                            |            | aliasing measured as shift variance                                       |

Every function returns the values it prints into the report, so the text quotes the figure.

The Hankel transform of a radial profile h in n dimensions (the paper's equation 2, with the factor
f^(1 - n/2) that makes it the n-D Fourier transform) is

    H(f) = 2 pi f^(1 - n/2) * integral_0^R h(r) J_(n/2 - 1)(2 pi f r) r^(n/2) dr,

evaluated with scipy's Bessel functions and normalised to H(0) = 1. For n = 1 it is the cosine
transform, for n = 3 the sine transform (2 / f) integral h(r) sin(2 pi f r) r dr.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

REPLICAS = {"1": 1.0, "√2": math.sqrt(2.0), "√3": math.sqrt(3.0)}
# Radial profiles (index units) as the paper plots them: nearest neighbour (box of half-width 0.5),
# linear (tent / cone of radius 1), and the renderer's Gaussian exp(-1.4 r^2) truncated at radius 2.
KERNELS = {
    "box": (lambda r: np.ones_like(r), 0.5, "tab:red"),
    "linear": (lambda r: 1.0 - r, 1.0, "tab:blue"),
    "gauss1.4": (lambda r: np.exp(-1.4 * r * r), 2.0, "k"),
}
FREQS = np.linspace(0.0, 3.0, 601)
PASSBAND_STRENGTH = 1.1  # kPassbandStrength, native/src/splat/passband.h
QUAD_POINTS = 1200


def hankel(profile, radius: float, n: int, freqs=FREQS) -> np.ndarray:
    """Radial n-D Fourier transform of a radial profile on [0, radius], normalised to 1 at f = 0."""
    from scipy.special import jv
    # Gauss-Legendre on [0, radius]: smooth integrands (the profiles' kinks sit at the ends).
    x, w = np.polynomial.legendre.leggauss(QUAD_POINTS)
    r = 0.5 * radius * (x + 1.0)
    w = 0.5 * radius * w
    h = profile(r)
    f = np.asarray(freqs, dtype=np.float64)[:, None]
    nu = 0.5 * n - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        core = jv(nu, 2.0 * np.pi * f * r) * r ** (0.5 * n) * (2.0 * np.pi * f) ** (-nu)
    # f -> 0: J_nu(z) z^-nu -> 1 / (2^nu Gamma(nu + 1))
    core[0] = r ** (0.5 * n) * r ** nu / (2.0 ** nu * math.gamma(nu + 1.0))
    # (2 pi f)^-nu is equation 2's f^(1 - n/2) up to a constant, which the normalisation removes.
    out = 2.0 * np.pi * (core * (h * w)[None, :]).sum(axis=1)
    return out / out[0]


def _zeros(freqs, H, lo=0.5, hi=2.6, tolerance=2e-3):
    """Frequencies where |H| has a local minimum below `tolerance` (sign changes and touching zeros)."""
    sel = (freqs >= lo) & (freqs <= hi)
    f, a = freqs[sel], np.abs(H[sel])
    idx = [i for i in range(1, len(a) - 1) if a[i] <= a[i - 1] and a[i] <= a[i + 1] and a[i] < tolerance]
    return [float(f[i]) for i in idx]


def _local_max_near(freqs, H, target, half_width=0.35):
    sel = (freqs > target - half_width) & (freqs < target + half_width)
    a = np.abs(H[sel])
    i = int(np.argmax(a))
    interior = 0 < i < len(a) - 1
    return float(freqs[sel][i]), float(a[i]), interior


def frequency_responses(path: Path) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = {}
    responses = {}
    fig, axes = plt.subplots(1, 5, figsize=(22, 4.2))
    for col, n in enumerate((1, 2, 3)):
        ax = axes[col]
        for name, (prof, radius, colour) in KERNELS.items():
            H = hankel(prof, radius, n)
            responses[(name, n)] = H
            ax.plot(FREQS, H, color=colour, label=name)
            stop = np.abs(H[FREQS >= 0.75]).max()
            values[f"{name} {n}D"] = {
                "zeros": [round(z, 3) for z in _zeros(FREQS, H)[:4]],
                "at_replicas": {k: float(np.interp(v, FREQS, H)) for k, v in REPLICAS.items()},
                "stop_band_max": float(stop),
                "at_half": float(np.interp(0.5, FREQS, H)),
            }
        for lab, d in REPLICAS.items():
            ax.axvline(d, color="0.6", lw=0.8, ls=":")
            ax.text(d, 1.02, lab, ha="center", fontsize=8, color="0.4")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylim(-0.25, 1.08)
        ax.set_xlabel("frequency (cycles per voxel)")
        ax.set_title(f"{n}-D radial frequency response", fontsize=10)
        ax.grid(alpha=0.3)
        if col == 0:
            ax.legend(fontsize=8)
    f_lin, a_lin, interior = _local_max_near(FREQS, responses[("linear", 3)], math.sqrt(3.0))
    values["linear 3D"]["local_max_near_sqrt3"] = {"f": f_lin, "abs_H": a_lin, "interior": interior}
    # 2-D maps over the replica lattice (Fig 5b, 5c)
    grid = np.linspace(-2.6, 2.6, 261)
    fx, fy = np.meshgrid(grid, grid)
    rho = np.hypot(fx, fy)
    for ax, name in zip(axes[3:], ("linear", "gauss1.4")):
        H2 = np.interp(rho, FREQS, responses[(name, 2)], right=0.0)
        im = ax.imshow(np.abs(H2), extent=(grid[0], grid[-1], grid[0], grid[-1]), origin="lower", cmap="magma",
                       vmin=0, vmax=0.12)
        lattice = np.arange(-2, 3)
        lx, ly = np.meshgrid(lattice, lattice)
        ax.scatter(lx[(lx != 0) | (ly != 0)], ly[(lx != 0) | (ly != 0)], s=10, c="cyan", marker="s")
        ax.set_title(f"|H| of 2-D {name} (clipped at 0.12); squares: replicas", fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.046)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return values


def combined_filters(path: Path) -> dict:
    """Footprint (the 3-D kernel's response on the image plane, Fourier slice theorem) times the
    post filter's response, along an image axis and along the diagonal."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pcvr_native as pn

    freqs = np.linspace(0.0, 2.5, 501)
    gauss = lambda a: (lambda r: np.exp(-a * r * r))  # noqa: E731
    splat = {"G1.4": hankel(gauss(1.4), 2.0, 3, freqs), "G2.0": hankel(gauss(2.0), 2.0, 3, freqs),
             "L": hankel(lambda r: 1.0 - r, 1.0, 3, freqs)}

    def post_1d(name, f):
        if name == "B":
            return np.sinc(f) ** 2   # tent of half-width 1 node
        a = {"G1.4": 1.4, "G2.0": 2.0}[name]
        t = np.linspace(-2.0, 2.0, 801)   # the truncated per-axis Gaussian the renderer uses
        w = np.exp(-a * t * t)
        return (w[None, :] * np.cos(2 * np.pi * f[:, None] * t[None, :])).sum(axis=1) / w.sum()

    # The passband compensation (native/src/splat/passband.h): [-a, 1 + 2a, -a] along each axis of nodes a
    # voxel apart, a = strength / 2 times the blur it pays back (the kernel's variance; with the bilinear
    # filter also its mean blur, 1/6 node^2 at large strides).
    variance = pn.kernel_info("gauss1.4")["variance"]
    compensation = {"G1.4": PASSBAND_STRENGTH / 2 * variance, "G1.4 + B": PASSBAND_STRENGTH / 2 * (variance + 1.0 / 6.0)}

    def sharpening(a, f):
        return 1.0 + 2.0 * a * (1.0 - np.cos(2.0 * np.pi * f))

    pairs = [("G1.4", None), ("G1.4", "B"), ("G1.4", "G1.4"), ("G2.0", "B"), ("G2.0", "G2.0"), ("L", "B"),
             ("G1.4", None, "compensated"), ("G1.4", "B", "compensated")]
    labels = {("G1.4", None): "G1.4 alone (regular splatting)", ("L", "B"): "L + B (bilinear spreading)",
              ("G1.4", None, "compensated"): "G1.4 alone, compensated (regular's default)",
              ("G1.4", "B", "compensated"): "G1.4 + B, compensated (PCVR's default)"}
    values = {}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for direction, ax in (("axis", axes[0]), ("diagonal", axes[1])):
        for pair in pairs:
            s, p = pair[:2]
            # The post filter and the compensation are separable: P(f) P(0) along an axis, P(f / sqrt 2)^2
            # along the diagonal.
            along = (lambda g: g(freqs)) if direction == "axis" else (lambda g: g(freqs / math.sqrt(2.0)) ** 2)
            post = 1.0 if p is None else along(lambda f: post_1d(p, f))
            if len(pair) > 2:
                a = compensation[s if p is None else f"{s} + {p}"]
                post = post * along(lambda f: sharpening(a, f))
            H = splat[s] * post
            lab = labels.get(pair, f"{s} + {p}")
            ax.plot(freqs, np.maximum(np.abs(H), 1e-7), label=lab, ls="--" if len(pair) > 2 else "-")
            rec = values.setdefault(lab, {})
            rec[direction] = {"at_0.25": float(np.interp(0.25, freqs, H)), "at_0.5": float(np.interp(0.5, freqs, H)),
                              "stop_band_max": float(np.abs(H[freqs >= 0.75]).max()),
                              "half_power_f": float(freqs[np.argmax(H < 0.5)])}
        for lab, d in REPLICAS.items():
            ax.axvline(d, color="0.6", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_ylim(1e-6, 2.5)
        ax.set_xlabel("frequency (cycles per voxel)")
        ax.set_title(f"|combined filter| along the image {direction} (log)", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return values


# ------------------------------------------------------------------------------------------------
# Images on the CT phantom

CT_SIZE, CT_QUICK = 128, 64
AXIAL = ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0))   # looking down the head's axis, as the paper's CT head


def _ct(quick):
    from pcvr_native import phantoms
    return phantoms.ct_phantom(CT_QUICK if quick else CT_SIZE)


def _render(grid, view, method, kernel="gauss1.4", post="bilinear", passband="paper"):
    """The paper's figures render the paper's passband unless told otherwise."""
    import pcvr_native as pn
    import views
    return np.asarray(pn.render_xray(grid, views.camera(view), method, kernel, post, passband=passband), dtype=np.float64)


def _rel(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.sqrt(np.mean(b ** 2)))


def subgrid_samples(grid, view):
    """The subgrid before post-convolution: PCVR with the bilinear post filter at the node pixels
    (phase 0, where the bilinear weights are 1 and 0), zero elsewhere."""
    import pcvr_native as pn
    import views
    stats = {}
    img = np.asarray(pn.render_xray(grid, views.camera(view), "pcvr", stats=stats, passband="paper"), dtype=np.float64)
    stride = int(stats.get("stride") or 1)
    # Nodes sit on pixels whose index is a multiple of the stride (post_convolution.h: pixel = stride * node).
    out = np.zeros_like(img)
    out[::stride, ::stride] = img[::stride, ::stride]
    return out, stride


def ct_comparison(path: Path, quick: bool) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import views

    ph = _ct(quick)
    grid = ph.grid()
    view = views.oblique(ph.values.shape, ph.index_to_world, 4, *AXIAL)
    reg = _render(grid, view, "regular")
    pcb = _render(grid, view, "pcvr")
    pcg = _render(grid, view, "pcvr", post="gauss1.4")
    bls = _render(grid, view, "bilinear_spread")
    sub, stride = subgrid_samples(grid, view)
    amp = 10.0
    diffs = {"a−b": reg - pcb, "b−c": pcb - pcg, "a−c": reg - pcg, "a−d": reg - bls}
    panels = [("(a) regular splatting", reg), ("(b) PCVR, bilinear post", pcb), ("(c) PCVR, Gaussian post", pcg),
              ("(d) bilinear spreading", bls), (f"(h) subgrid before post-convolution (L={stride})", sub)]
    panels += [(f"{k} ×{amp:g}", v) for k, v in diffs.items()]
    peak = reg.max()
    fig, axes = plt.subplots(2, 5, figsize=(20, 8.4))
    for ax, (title, im) in zip(axes.flat, panels):
        if "×" in title:
            ax.imshow(0.5 + amp * im / peak, cmap="gray", vmin=0, vmax=1)
        else:
            ax.imshow(im / peak, cmap="gray", vmin=0, vmax=1)
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    axes.flat[-1].axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)
    return {"size": ph.values.shape[0], "magnification": 4, "stride": stride, "image": [view["width"], view["height"]],
            "rel_vs_regular": {"pcvr bilinear post": _rel(pcb, reg), "pcvr gaussian post": _rel(pcg, reg),
                               "bilinear spreading": _rel(bls, reg)},
            "amplification": amp}


def shifted(view, pixels: int) -> dict:
    """The same orthographic view moved `pixels` pixels to the right (image content moves left)."""
    v = dict(view)
    m = np.asarray(view["matrix_world"], dtype=np.float64).copy()
    pixel = view["ortho_scale"] / max(view["width"], view["height"])
    m[:3, 3] += m[:3, 0] * pixel * pixels
    v["matrix_world"] = m.tolist()
    return v


def shift_variance(grid, view, method, post="bilinear", kernel="gauss1.4", passband="paper") -> float:
    """Aliasing as shift variance: render the view and the view moved by 1 .. L-1 pixels; an alias-free
    renderer gives the same image moved by those pixels. RMS of the change over RMS of the image,
    averaged over the shifts (stride L = the magnification here)."""
    base = _render(grid, view, method, kernel, post, passband)
    m = int(round(view["magnification"]))
    errs = []
    for s in range(1, max(m, 2)):
        moved = _render(grid, shifted(view, s), method, kernel, post, passband)
        a, b = moved[:, :-s], base[:, s:]
        errs.append(_rel(a, b))
    return float(np.mean(errs))


def bilinear_aliasing(path: Path, quick: bool) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import views

    ph = _ct(quick)
    grid = ph.grid()
    mags = (1, 2, 3, 4)
    vs = {m: views.oblique(ph.values.shape, ph.index_to_world, m, *AXIAL) for m in mags + (8,)}
    images = {m: _render(grid, vs[m], "bilinear_spread") for m in mags}
    regular = {m: _render(grid, vs[m], "regular") for m in mags}
    gauss4 = _render(grid, vs[4], "pcvr")
    panels = [(f"(i) bilinear spreading, {m}×", images[m], regular[m]) for m in mags]
    panels.append(("(k) PCVR gauss1.4 + bilinear, 4×", gauss4, regular[4]))
    fig, axes = plt.subplots(2, 5, figsize=(21, 8.4))
    peak = regular[4].max()
    # The same world window at every magnification: the skull's rim on the right of the head.
    for col, (title, im, ref) in enumerate(panels):
        h, w = im.shape
        window = (slice(int(0.35 * h), int(0.65 * h)), slice(int(0.70 * w), int(0.95 * w)))
        axes[0, col].imshow(im[window] / peak, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        axes[0, col].set_title(title, fontsize=10)
        axes[1, col].imshow(0.5 + 10.0 * (im - ref)[window] / peak, cmap="gray", vmin=0, vmax=1,
                            interpolation="nearest")
        axes[1, col].set_title("minus regular splatting, ×10", fontsize=9)
    for ax in axes.flat:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    measured = {}
    for m in (2, 3, 4, 8):
        measured[m] = {
            "bilinear spreading": shift_variance(grid, vs[m], "bilinear_spread"),
            "pcvr gauss1.4 + bilinear": shift_variance(grid, vs[m], "pcvr"),
            "pcvr gauss1.4 + gauss1.4": shift_variance(grid, vs[m], "pcvr", post="gauss1.4"),
            "regular": shift_variance(grid, vs[m], "regular"),
            "pcvr gauss1.4 + bilinear, compensated": shift_variance(grid, vs[m], "pcvr", passband="compensated"),
            "regular, compensated": shift_variance(grid, vs[m], "regular", passband="compensated"),
        }
    return {"size": ph.values.shape[0], "shift_variance": measured}


def run(fig_dir: Path, quick: bool, log) -> dict:
    fig_dir.mkdir(parents=True, exist_ok=True)
    out = {}
    log("figures: frequency responses")
    out["frequency_responses"] = frequency_responses(fig_dir / "frequency_responses.png")
    log("figures: combined filters")
    out["combined_filters"] = combined_filters(fig_dir / "combined_filters.png")
    log("figures: CT comparison")
    out["ct_comparison"] = ct_comparison(fig_dir / "ct_comparison.png", quick)
    log("figures: bilinear spreading's aliasing")
    out["bilinear_aliasing"] = bilinear_aliasing(fig_dir / "bilinear_aliasing.png", quick)
    return out
