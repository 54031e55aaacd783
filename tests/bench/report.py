"""docs/benchmarks.md and its plots from the results of run_benchmarks.py.

Everything here reads the results dictionary only, so a report can be rewritten from
out/bench/results.json (``run_benchmarks.py --from-results out/bench/results.json``) without
measuring again.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import analysis_report
import batch_bench
import big_volume_bench
import clipping_bench
import ct_head
import drr_bench
import evidence_report
import magnification_curve
import materials_bench
import minification_bench
import passband_bench
import shaded_levels
import shaded_report
import shadows_bench
import speed_of_light as sol
import viewport_bench
from xray_plots import GOALS, LABELS, METHOD_ORDER, main_volume, plot_speedup, plot_time_vs_error, vol_name

# Image-sized traffic per pixel: clear the float32 image (4 B) and the post-convolution's += into it
# (4 B read, 4 B write); the image then moves into the result without a copy.
IMAGE_BYTES_PER_PIXEL = 12


def taps(key: str, mag: float) -> float:
    if key == "regular":
        return sol.regular_taps(mag)
    if key == "bilinear_spread":
        return 4.0
    return sol.pcvr_taps()


def fmt(x, spec=".1f", missing="–"):
    if x is None or (isinstance(x, float) and (math.isnan(x) or math.isinf(x))):
        return missing
    return format(x, spec)


class SolData:
    def __init__(self, results: dict):
        s = results.get("sol") or {}
        self.ok = "tests" in s
        self.error = s.get("error")
        if self.ok:
            self.measured = {"tests": {(r["test"], r["threads"]): r for r in s["tests"]}, "threads": s["threads"]}
            self.threads = s["threads"]
            self.n = s.get("n")

    def get(self, test, key, threads=None):
        return sol.get(self.measured, test, key, threads) if self.ok else float("nan")

    def bounds(self, taps_):
        return sol.bounds(self.measured, taps_) if self.ok else None

    def rate(self, test, key, per_core=True):
        """All-core capability (see speed_of_light.machine_rate)."""
        return sol.machine_rate(self.measured, test, key, per_core) if self.ok else float("nan")


# ------------------------------------------------------------------------------------------------
# Markdown (the plots are xray_plots.py's)

def goal_lines(results: dict, sd: SolData) -> list[str]:
    v = main_volume(results)
    if v is None:
        return ["No volumes were measured."]
    cfgs = v["configs"]
    out = [f"Judged on the {vol_name(v)} volume ({v['active_voxels'] / 1e6:.1f} M active voxels), oblique view, "
           f"`pcvr` with the default `gauss1.4` splat kernel and `bilinear` post filter unless noted.", "",
           "| goal | target | measured | verdict |", "|---|---|---|---|"]

    def verdict(ok):
        return "met" if ok else "**MISSED**"

    for mag, key in ((4, "speedup_m4"), (8, "speedup_m8")):
        cfg = cfgs.get(str(mag))
        if cfg is None:
            out.append(f"| pcvr speed-up vs regular at m={mag} | ≥ {GOALS[key]:.0f}x | not measured (magnification not run) | – |")
            continue
        s = cfg["methods"]["pcvr_bilinear"]["speedup"]
        g = cfg["methods"]["pcvr_gauss"]["speedup"]
        out.append(f"| pcvr speed-up vs regular at m={mag} | ≥ {GOALS[key]:.0f}x | {s:.1f}x (with gauss1.4 post filter: {g:.1f}x) "
                   f"| {verdict(s >= GOALS[key])} |")
    errs = {int(k): 100 * c["methods"]["pcvr_bilinear"]["rel_rmse"] for k, c in cfgs.items()}
    worst = max(errs.values())
    out.append(f"| relative RMSE of pcvr (gauss1.4 + bilinear) vs exact | < {GOALS['rel_rmse_pct']:.0f}% | "
               + ", ".join(f"m={k}: {e:.2f}%" for k, e in sorted(errs.items())) + f" | {verdict(worst < GOALS['rel_rmse_pct'])} |")
    rates = {int(k): c["methods"]["pcvr_bilinear"]["mvox_per_s"] for k, c in cfgs.items()}
    met = [k for k, r in sorted(rates.items()) if r >= GOALS["pcvr_mvox"]]
    lim = (v.get("limits") or {}).get("configs", {})
    one = {int(k): v["active_voxels"] / r["pcvr_1thread"] / 1e6 for k, r in lim.items() if "pcvr_1thread" in r}
    out.append(f"| pcvr throughput, oblique view | ≥ {GOALS['pcvr_mvox']:.0f} M active voxels/s | "
               + ", ".join(f"m={k}: {r:.0f}" for k, r in sorted(rates.items()))
               + (" (one thread: " + ", ".join(f"m={k}: {r:.0f}" for k, r in sorted(one.items())) + ")" if one else "")
               + f" | {verdict(len(met) == len(rates)) if met else '**MISSED**'}"
               + (f" (met at m={', '.join(map(str, met))} only)" if met and len(met) < len(rates) else "") + " |")
    if sd.ok:
        b = sd.bounds(sol.pcvr_taps())
        best = max(rates.values())
        out.append(f"| (context) speed of light of a 16-tap splat here | – | {b['sol'] / 1e6:.0f} M voxels/s "
                   f"({b['sol_limiter']} bound); pcvr reaches {100 * best / (b['sol'] / 1e6):.0f}% of it at best | – |")
    missed = [mag for mag, key in ((4, "speedup_m4"), (8, "speedup_m8"))
              if str(mag) in cfgs and cfgs[str(mag)]["methods"]["pcvr_bilinear"]["speedup"] < GOALS[key]]
    if missed:
        out += ["", "The speed-up goals assume a `regular` that pays about as much per tap as pcvr. In orthographic views "
                "`regular` takes its whole footprint window from a phase table (plain loads, no per-tap gathers) in "
                "the same batched splat as pcvr, which makes its taps cheaper than pcvr's, whose fixed per-voxel "
                "work is spread over 16 taps only. Against that baseline the ratios above are what PCVR earns on "
                "this machine. See *What limits us*."]
    return out


TABLE_HEAD = ["| {} | image | method | runs | median ms | cores busy | speed-up | M vox/s | peak MB | rel RMSE % | PSNR dB |",
              "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]


def method_rows(label: str, cfg: dict) -> list[str]:
    """One table row per method of a configuration, `label` and the image size on the first."""
    out = []
    first = True
    for key in METHOD_ORDER:
        m = cfg["methods"].get(key)
        if not m:
            continue
        mem = m.get("memory") or {}
        peak = mem.get("extra_mb")
        strides = m.get("strides") or ([m["stride"]] if m.get("stride") else [])
        stride = ""
        if key != "regular" and strides:
            stride = f" (L={strides[0]:.3g})" if len(strides) == 1 else f" (L={min(strides):.3g}–{max(strides):.3g})"
        out.append("| {} | {} | {}{} | {} | {} | {} | {} | {} | {} | {} | {} |".format(
            label if first else "", f"{cfg['width']}×{cfg['height']}" if first else "", LABELS[key], stride, m["runs"],
            fmt(1e3 * m["median_s"], ".1f"), fmt(m.get("cores_busy"), ".2f"),
            "1 (ref)" if key == "regular" else fmt(m["speedup"], ".2f") + "x",
            fmt(m["mvox_per_s"], ".1f"), fmt(peak, ".1f" if peak is not None and peak < 10 else ".0f"),
            fmt(100 * m["rel_rmse"], ".3f"), fmt(m["psnr"], ".1f")))
        first = False
    return out


def volume_table(v: dict) -> list[str]:
    out = [f"#### {vol_name(v)}: {v['active_voxels']:,} active voxels ({100 * v['fill']:.1f}% of the box)", ""]
    out += [TABLE_HEAD[0].format("m"), TABLE_HEAD[1]]
    for mag, cfg in sorted(v["configs"].items(), key=lambda kv: int(kv[0])):
        out += method_rows(str(mag), cfg)
    ex = ", ".join(f"m={k}: {c['exact_s']:.2g} s" for k, c in sorted(v["configs"].items(), key=lambda kv: int(kv[0])))
    out += ["", f"Exact reference (1 pixel in 49) took {ex}. Grid built from the dense array in {v['grid_build_s']:.2f} s; "
            f"block cache {1e3 * v['block_cache_s']:.0f} ms (paid once, before timing)."]
    errors = [f"{LABELS[k]} m={mag}: {m['memory']['error']}" for mag, c in v["configs"].items()
              for k, m in c["methods"].items() if isinstance(m.get("memory"), dict) and "error" in m["memory"]]
    if errors:
        out += ["", "Memory measurement failed for: " + "; ".join(errors)]
    return out


def perspective_section(results: dict) -> list[str]:
    persp = [v for v in results["volumes"] if "perspective" in v]
    if not persp:
        return []
    v = persp[0]
    cfg = v["perspective"]
    pc = cfg["methods"]["pcvr_bilinear"]
    out = ["### Perspective", "",
           f"{vol_name(v)} through a pinhole camera along the same direction, its eye {cfg['distance_diagonals']:g} volume "
           f"diagonals from the volume's centre, where a voxel spans {cfg['magnification']:g} pixels: from "
           f"{cfg['min_magnification']:.1f} pixels per voxel on the far side to {cfg['max_magnification']:.1f} on the near "
           "side. Every voxel has its own footprint here (size and shape change with depth and position), its block's "
           "linearised in float eight voxels at a time, its window from the phase table of its block's footprint; pcvr "
           "splats each depth band into the subgrid of its own stride and post-convolves each band. The bands' strides "
           "lie 2^(1/8) apart from the most magnification down, so a voxel spans between 0.92 and 1 subgrid nodes and "
           "pcvr adds 4 x 4 taps per voxel, as orthographic views do.", "",
           TABLE_HEAD[0].format("view"), TABLE_HEAD[1]]
    out += method_rows("persp.", cfg)
    out += ["", f"Exact reference (1 pixel in 49) took {cfg['exact_s']:.2g} s. pcvr + bilinear: {pc['speedup']:.1f}x "
            f"regular's speed at {100 * pc['rel_rmse']:.2f}% relative RMSE against exact."]
    return out


def accuracy_notes(results: dict) -> list[str]:
    """Observations on the error columns, from the numbers."""
    out = []
    pairs = [(v, mag, c["methods"]) for v in results["volumes"] for mag, c in v["configs"].items() if int(mag) >= 2]
    if not pairs:
        return out
    better = [p for p in pairs if p[2]["bilinear_spread"]["rel_rmse"] < p[2]["pcvr_bilinear"]["rel_rmse"]]
    worst_pcvr = max(100 * m["pcvr_bilinear"]["rel_rmse"] for _, _, m in pairs)
    worst_gauss = max(100 * m["pcvr_gauss"]["rel_rmse"] for _, _, m in pairs)
    worst_reg = max(100 * m["regular"]["rel_rmse"] for _, _, m in pairs)
    out.append(f"- At m ≥ 2 the largest relative RMSE of pcvr is {worst_pcvr:.2f}% with the bilinear post filter and "
               f"{worst_gauss:.2f}% with gauss1.4 (the wider post filter blurs more, as the paper predicts); regular "
               f"splatting is at most {worst_reg:.3f}% from exact (its footprint table's resolution).")
    if len(better) > len(pairs) / 2:
        out.append(f"- Bilinear spreading comes out *more* accurate than pcvr + bilinear in {len(better)} of {len(pairs)} "
                   "configurations with m ≥ 2. These phantoms are smooth (band-limited noise), so the aliasing the paper "
                   "warns about barely shows, while pcvr's post filter adds its blur on top of the kernel's (per axis "
                   "variance 1/6 voxel² for the bilinear filter). The paper's case for pcvr over bilinear spreading rests on "
                   "sharper detail than these two volumes contain.")
    else:
        out.append(f"- Bilinear spreading is less accurate than pcvr + bilinear in {len(pairs) - len(better)} of "
                   f"{len(pairs)} configurations with m ≥ 2.")
    return out


def sol_section(results: dict, sd: SolData) -> list[str]:
    out = ["### Speed of light", ""]
    if not sd.ok:
        return out + [f"Not measured ({sd.error or 'skipped with --no-sol'})."]
    nt = max(sd.threads)
    ghz = sd.get("clock", "ghz", 1)
    out += [
        "`tests/bench/sol_kernels.c`, compiled at bench time with `cc -O3 -march=native -fopenmp`, measures the "
        "primitives a splat is made of (best of several short runs, so other work on the machine shows less). "
        f"Columns: one thread, and all {nt} cores.", "",
        "| primitive | 1 thread | all cores | note |", "|---|---:|---:|---|",
        f"| core clock (dependent integer adds) | {ghz:.2f} GHz | | |",
        f"| DRAM read (sum of 512 MiB) | {sd.get('bw_read', 'gbps', 1):.1f} GB/s | {sd.get('bw_read', 'gbps'):.1f} GB/s | |",
        f"| DRAM copy (read + write counted) | {sd.get('bw_copy', 'gbps', 1):.1f} GB/s | {sd.get('bw_copy', 'gbps'):.1f} GB/s | |",
        f"| fp32 FMA, 256-bit | {sd.get('fma_ymm', 'gflops', 1):.0f} GFLOP/s | {sd.get('fma_ymm', 'gflops'):.0f} GFLOP/s | "
        f"{sd.get('fma_ymm', 'fma_per_s', 1) / (ghz * 1e9):.2f} FMA instructions per cycle |",
        f"| fp32 FMA, 512-bit | {fmt(sd.get('fma_zmm', 'gflops', 1), '.0f')} GFLOP/s | {fmt(sd.get('fma_zmm', 'gflops'), '.0f')} GFLOP/s | "
        "AVX-512 brings no more FLOPs here |",
        f"| 256-bit stores (L1) | {sd.get('store_ymm', 'stores_per_s', 1) / 1e9:.2f} G/s | {sd.get('store_ymm', 'stores_per_s') / 1e9:.2f} G/s | "
        f"{sd.get('store_ymm', 'stores_per_s', 1) / (ghz * 1e9):.2f} per cycle |",
        f"| 256-bit load+add+store of doubles, 4x4 block moving along a row | {sd.get('rmw_ymm', 'stores_per_s', 1) / 1e9:.2f} G/s | "
        f"{sd.get('rmw_ymm', 'stores_per_s') / 1e9:.2f} G/s | the splat's accumulate pattern |",
        f"| the same, each 4x4 block overlapping the previous one (shifted by 1 double) | "
        f"{sd.get('rmw_overlap_ymm', 'stores_per_s', 1) / 1e9:.2f} G/s | {sd.get('rmw_overlap_ymm', 'stores_per_s') / 1e9:.2f} G/s | "
        "as consecutive voxels' footprints overlap: loads wait for misaligned earlier stores |",
        f"| 8-lane gather (vpgatherdd, 16 KiB table) | {sd.get('gather_ymm', 'gathers_per_s', 1) / 1e6:.0f} M/s | "
        f"{sd.get('gather_ymm', 'gathers_per_s') / 1e6:.0f} M/s | "
        f"{ghz * 1e9 / sd.get('gather_ymm', 'gathers_per_s', 1):.1f} cycles each |",
        f"| 16-lane gather (AVX-512) | {fmt(sd.get('gather_zmm', 'gathers_per_s', 1) / 1e6, '.0f')} M/s | "
        f"{fmt(sd.get('gather_zmm', 'gathers_per_s') / 1e6, '.0f')} M/s | same lanes per second as 8-lane |",
        "",
        "**Model.** A splat reads each active voxel once (4 bytes of value, 1 mask bit and its share of the block "
        f"header: {sol.BYTES_PER_VOXEL:.2f} bytes) and adds `taps` weights into a double-precision buffer. "
        "With doubles one 256-bit store carries 4 taps, so a voxel costs `taps / 4` stores; the least arithmetic per 8 taps "
        f"is {sol.OPS_PER_8_TAPS:.0f} vector ops (2 FMAs for the quadratic rho², 1 multiply by the value, 2 four-wide double adds). "
        "PCVR splats 16 taps per voxel (4×4 subgrid nodes) at any magnification, bilinear spreading 4, regular splatting "
        "π(2m)² (the radius-2 footprint at m pixels per voxel). The speed of light is the smallest of the memory, "
        "store and compute bounds; the gather bound (one table lookup per tap) belongs to the table formulation the "
        "renderer uses and is shown apart. All bounds are for all cores: per-core rates (FMA, stores, gathers) are "
        f"taken as {nt} × the single-thread rate unless the all-core run measured more (on a shared machine the "
        "all-core runs suffer most from other work); DRAM bandwidth as the best of both runs.", "",
        "| splat | taps/voxel | memory | store | compute | **speed of light** | gather (table) |",
        "|---|---:|---:|---:|---:|---:|---:|"]
    rows = [("pcvr (4×4)", sol.pcvr_taps()), ("bilinear spread (2×2)", 4.0)]
    mags = sorted({int(k) for v in results["volumes"] for k in v["configs"]})
    rows += [(f"regular, m={m}", sol.regular_taps(m)) for m in mags]
    for name, t in rows:
        b = sd.bounds(t)
        out.append(f"| {name} | {t:.0f} | {b['memory'] / 1e6:,.0f} M/s | {b['store'] / 1e6:,.0f} M/s | "
                   f"{b['compute'] / 1e6:,.0f} M/s | **{b['sol'] / 1e6:,.0f} M/s** ({b['sol_limiter']}) | {b['gather'] / 1e6:,.0f} M/s |")
    out += ["", "How close each method comes (active voxels per second over the speed of light for its own tap count), "
            "on every volume:", "", "| volume | m | " + " | ".join(LABELS[k] for k in METHOD_ORDER) + " |",
            "|---|---:|" + "---:|" * len(METHOD_ORDER)]
    for v in results["volumes"]:
        for mag, cfg in sorted(v["configs"].items(), key=lambda kv: int(kv[0])):
            cells = []
            for k in METHOD_ORDER:
                m = cfg["methods"].get(k)
                if not m:
                    cells.append("–")
                    continue
                b = sd.bounds(taps(k, int(mag)))
                cells.append(f"{100 * m['mvox_per_s'] * 1e6 / b['sol']:.1f}%")
            out.append(f"| {vol_name(v)} | {mag} | " + " | ".join(cells) + " |")
    splat_rows = [("splat_scalar", "plain C, 16 taps (compiler's code)"),
                  ("splat_avx2", "AVX2, the renderer's first formulation: 2 gathers + 4 load-add-store per voxel"),
                  ("splat_noscatter", "… weights only (gathers), no stores"),
                  ("splat_nogather", "… stores only, constant weights"),
                  ("splat_phase", "weights from a per-view table of 32×32 sub-node phases (no gathers)")]
    out += ["", f"The PCVR first stage alone, in C (`splat_*` in sol_kernels.c: a dense {sd.n}³ volume in 8³ blocks, the "
            "same oblique projection, one private subgrid per thread):", "",
            "| loop | 1 thread | all cores |", "|---|---:|---:|"]
    for test, desc in splat_rows:
        out.append(f"| {desc} | {sd.get(test, 'voxels_per_s', 1) / 1e6:.0f} M vox/s | {sd.get(test, 'voxels_per_s') / 1e6:.0f} M vox/s |")
    return out


def limits_section(results: dict, sd: SolData) -> list[str]:
    v = main_volume(results)
    out = ["### What limits us", ""]
    if v is None or "limits" not in v:
        return out + ["Not measured."]
    lim = v["limits"]
    out += [f"Measured on {vol_name(v)}. *Image-sized work* is the time of the same render on a grid with one voxel per "
            f"8³ block ({lim['lattice_voxels']:,} voxels, so every block and image tile is touched but almost nothing is "
            "splatted): allocating and clearing buffers, post-convolution, reducing the per-thread buffers, converting "
            "the image. The rest of the time is the splatting itself; *splat rate* is active voxels over that rest.", "",
            "| m | image | method | total ms | image-sized ms (share) | splat ms | splat rate M vox/s |",
            "|---:|---|---|---:|---:|---:|---:|"]
    bullets = []
    for mag, row in sorted(lim["configs"].items(), key=lambda kv: int(kv[0])):
        cfg = v["configs"][mag]
        first = True
        for k in METHOD_ORDER:
            total = cfg["methods"][k]["median_s"]
            img = row.get(k, float("nan"))
            splat = max(total - img, 1e-9)
            size = f"{cfg['width']}×{cfg['height']}" if first else ""
            out.append(f"| {mag if first else ''} | {size} | {LABELS[k]} | {1e3 * total:.0f} | "
                       f"{1e3 * img:.0f} ({100 * img / total:.0f}%) | {1e3 * splat:.0f} | {v['active_voxels'] / splat / 1e6:.0f} |")
            first = False
    out.append("")
    mags = sorted(lim["configs"], key=int)
    # Data-driven observations.
    pc = [(int(m), v["configs"][m]["methods"]["pcvr_bilinear"]["median_s"], lim["configs"][m]["pcvr_bilinear"]) for m in mags]
    if pc:
        m_hi, t_hi, i_hi = pc[-1]
        splat_rates = [v["active_voxels"] / max(t - i, 1e-9) / 1e6 for _, t, i in pc]
        share_lo, share_hi = 100 * pc[0][2] / pc[0][1], 100 * i_hi / t_hi
        head = ("Splatting dominates pcvr" if share_hi < 40 else
                "Image-sized work dominates pcvr at high magnification" if share_hi > 60 else
                "pcvr's time splits between splatting and image-sized work")
        bullets.append(f"**{head}.** Its splat stage runs at {min(splat_rates):.0f}–{max(splat_rates):.0f} M vox/s "
                       f"across magnifications; image-sized work is {share_lo:.0f}% of pcvr's time at m={pc[0][0]} and "
                       f"{share_hi:.0f}% at m={m_hi}.")
        cfg_hi = v["configs"][str(m_hi)]
        pixels = cfg_hi["width"] * cfg_hi["height"]
        if sd.ok:
            bw = sd.get("bw_copy", "gbps") * 1e9
            floor = pixels * IMAGE_BYTES_PER_PIXEL / bw
            bullets.append(f"**Image-sized work against its floor**: at m={m_hi} ({pixels / 1e6:.1f} M pixels) it takes "
                           f"{1e3 * i_hi:.0f} ms, {1e9 * i_hi / pixels:.1f} ns per pixel. Clearing the float32 image and "
                           f"one read-modify-write by the post-convolution move about "
                           f"{IMAGE_BYTES_PER_PIXEL} bytes per pixel: {1e3 * floor:.0f} ms at the measured copy bandwidth, so "
                           f"this part runs at {100 * floor / i_hi:.0f}% of its bandwidth floor."
                           + (f" Part of the gap is first touch of fresh buffers: a pcvr render at m={m_hi} faults in "
                              f"{lim['configs'][str(m_hi)]['pcvr_fault_mb']:.0f} MB and spends "
                              f"{1e3 * lim['configs'][str(m_hi)]['pcvr_sys_s']:.0f} ms of CPU time in the kernel "
                              f"(transparent huge pages: `{lim.get('thp', '?')}`; the renderer maps image-sized buffers "
                              f"as huge pages where the kernel allows and faults them in on all cores before use)."
                              if "pcvr_fault_mb" in lim["configs"].get(str(m_hi), {}) else ""))
            c_avx = sd.get("splat_avx2", "voxels_per_s", 1) / 1e6
            c_nog = sd.get("splat_nogather", "voxels_per_s", 1) / 1e6
            c_nos = sd.get("splat_noscatter", "voxels_per_s", 1) / 1e6
            c_ph = sd.get("splat_phase", "voxels_per_s", 1) / 1e6
            one = [(int(m), r["pcvr_1thread"]) for m, r in lim["configs"].items() if "pcvr_1thread" in r]
            head = ("In C, the table gathers limit the 16-tap loop more than the stores do" if c_nos < c_nog else
                    "In C, the stores limit the 16-tap loop more than the table gathers do")
            text = (f"**{head}.** On one thread, "
                    f"`splat_avx2` (the renderer's original 4×4 formulation: 2 gathers + 4 read-modify-writes) does "
                    f"{c_avx:.0f} M vox/s; with constant weights (no gathers) {c_nog:.0f} M vox/s, with the gathers but no "
                    f"stores {c_nos:.0f} M vox/s. An 8-lane gather costs "
                    f"{sd.get('clock', 'ghz', 1) * 1e9 / sd.get('gather_ymm', 'gathers_per_s', 1):.1f} cycles here, about "
                    f"one cycle per lane. Taking the 16 weights from a table indexed by the sub-node phase (orthographic "
                    f"views share one footprint shape; `splat_phase`, 4 plain loads) does {c_ph:.0f} M vox/s.")
            if one:
                best_m, best_t = min(one, key=lambda x: x[1])
                r1 = v["active_voxels"] / best_t / 1e6
                text += (f" The renderer on one thread (whole pcvr render, m={best_m}) does {r1:.0f} M vox/s: "
                         f"{100 * r1 / c_ph:.0f}% of the C phase-table loop, {100 * r1 / c_avx:.0f}% of the C gather loop. "
                         f"The C loops take one voxel at a time through a long dependent chain (position, floor, phase, "
                         f"blend, weights, accumulate); the renderer computes positions, phases and blend weights for "
                         f"eight voxels in one vector pass and then adds the windows, whose chains are short and "
                         f"independent (`native/src/splat/phase_splat.h`), and its time also covers planning, the "
                         f"post-convolution and the image, which the C loops do not do.")
            bullets.append(text)
            b = sd.bounds(sol.pcvr_taps())
            bullets.append(f"**Stores: the port bound is far, the accumulate pattern is not.** 4 stores per voxel at the "
                           f"measured store rate would allow {b['store'] / 1e6:,.0f} M vox/s and a plain 4-row "
                           f"read-modify-write {sd.rate('rmw_ymm', 'stores_per_s') / 4e6:,.0f} M vox/s; but consecutive "
                           f"voxels of a block land less than one node apart, so each voxel's rows overlap the previous "
                           f"voxel's at a misaligned offset, and that pattern measures only "
                           f"{sd.rate('rmw_overlap_ymm', 'stores_per_s') / 4e6:,.0f} M vox/s (all cores): a load "
                           f"waits until the overlapping store is written. The renderer lets consecutive voxels take "
                           f"turns over four float copies of a block-sized tile in L1, so an update waits only on the "
                           f"voxel four places back, and adds the copies into the double grid once per block. "
                           f"Memory bandwidth ({b['memory'] / 1e6:,.0f} M vox/s) is no limit at all.")
    reg = [(int(m), v["configs"][m]["methods"]["regular"]["median_s"], lim["configs"][m]["regular"]) for m in mags]
    if reg and pc and sd.ok:
        m_hi, t_hi, i_hi = reg[-1]
        window_hi = (4 * m_hi) ** 2  # the phase-table window regular splats (its disc: regular_taps)
        reg_rate = v["active_voxels"] * window_hi / max(t_hi - i_hi, 1e-9) / 1e9
        pc_rate = v["active_voxels"] * sol.pcvr_taps() / max(pc[-1][1] - pc[-1][2], 1e-9) / 1e9
        bullets.append(f"**Regular splatting pays per pixel**: at m={m_hi} a voxel's footprint window has "
                       f"{window_hi:.0f} taps ({sol.regular_taps(m_hi):.0f} of them inside the disc) instead of 16. "
                       f"In orthographic views regular takes its weights from the same kind of phase table as pcvr "
                       f"(plain loads and a blend, no gathers) in the same batched splat, so it is as optimised: "
                       f"its splat stage runs at "
                       f"{reg_rate:.2f} G window taps/s, pcvr's 16-tap loop at {pc_rate:.2f} G taps/s. The speed-ups "
                       f"above are the tap ratio ({window_hi / 16:.0f}x at m={m_hi}) divided by regular's per-tap "
                       f"advantage ({reg_rate / pc_rate:.2f}x): pcvr's per-voxel work (position, phase blend, four "
                       f"row updates) is spread over 16 taps only, less what pcvr's image-sized work takes back.")
    th = [(int(m), r["pcvr_1thread"], r["pcvr_all_threads"]) for m, r in lim["configs"].items() if "pcvr_1thread" in r]
    if th:
        nt = os.cpu_count() or 2
        effs = [t1 / (nt * tn) for _, t1, tn in th]
        bullets.append(f"**Threads**: pcvr on all {nt} cores against one: parallel efficiency "
                       + ", ".join(f"m={m}: {100 * e:.0f}%" for (m, _, _), e in zip(sorted(th), effs))
                       + " (the machine is shared, so some of the loss is other work).")
    out += [f"- {b}" for b in bullets]
    return out


def write(results: dict, output: Path) -> None:
    output = Path(output)
    img_dir = output.parent / "img"
    img_dir.mkdir(parents=True, exist_ok=True)
    tve = img_dir / "bench_time_vs_error.png"
    spd = img_dir / "bench_speedup.png"
    if results["volumes"]:
        plot_time_vs_error(results, tve)
        plot_speedup(results, spd)
    rel = lambda p: os.path.relpath(p, output.parent)  # noqa: E731
    sd = SolData(results)
    mi = results["machine"]
    st = results["settings"]
    lines = ["# PCVR benchmarks", ""]
    if results.get("quick"):
        lines += ["> **Smoke run (`--quick`)**: small volumes, one repetition. These numbers only show that the "
                  "benchmark works; run `make bench` for the real ones.", ""]
    lines += [
        f"Generated by `make bench` (`tests/bench/run_benchmarks.py`) on {results['date']}, commit {mi.get('commit', '?')}, "
        f"in {results.get('total_s', 0) / 60:.0f} minutes. Raw numbers: `out/bench/results.json` (not committed).", "",
        f"**Machine**: {mi.get('cpu', '?')}, {mi.get('cpus', '?')} CPUs ({mi.get('threads_per_core', '?')} thread per core"
        + (f", {mi['hypervisor']} virtual machine" if mi.get("hypervisor") else "") + f"), SIMD {', '.join(mi.get('simd', []))}, "
        f"L2 {mi.get('l2', '?')}, L3 {mi.get('l3', '?')}, {mi.get('memory_gb', 0):.0f} GiB RAM; {mi.get('platform', '')}; "
        f"Python {mi.get('python')}, numpy {mi.get('numpy')}, {mi.get('cc', '')}. The native module"
        + (f" (installed {mi['pcvr_native_built']})" if mi.get("pcvr_native_built") else "")
        + " is built for `-march=x86-64-v3` (AVX2 + FMA; the CMake default). Renders use "
        + ("all cores" if st["threads"] == 0 else f"{st['threads']} threads") + ". Load average "
        f"{results['load_before'][0]:.2f} before and {results.get('load_after', [float('nan')])[0]:.2f} after the run: "
        "the machine is shared, which is why every ratio below is taken within one run. Absolute times of two runs "
        "at different moments can differ by a third; the *cores busy* column shows how much CPU the renders got.", ""]
    fig_dir = output.parent / "figures"
    lines += evidence_report.section(results, output.parent, fig_dir)
    lines += analysis_report.figures_section(results.get("figures"), output.parent, fig_dir)
    lines += analysis_report.kernel_section(results.get("kernel_search"))
    lines += shaded_report.section(results, output.parent, fig_dir)
    lines += ct_head.section(results.get("ct_head"))
    lines += clipping_bench.section(results.get("clipping"))
    lines += drr_bench.section(results.get("drr"))
    lines += shadows_bench.section(results.get("shadows"))
    lines += materials_bench.section(results.get("materials"))
    lines += viewport_bench.section(results.get("viewport"))
    lines += minification_bench.section(results.get("minification"))
    lines += shaded_levels.section(results.get("shaded_levels"))
    lines += big_volume_bench.section(results.get("big_volume"))
    lines += batch_bench.section(results.get("batch"))
    lines += magnification_curve.section(results.get("magnification_curve"))
    lines += passband_bench.section(results.get("passband"))
    if not results["volumes"]:
        output.write_text("\n".join(lines))
        return
    lines += ["## Throughput: PCVR's own speed, memory and limits", "",
              "The rest of this page measures PCVR alone on larger volumes: speed-ups over regular splatting, "
              "memory, the speed of light of a splat on this machine, and what limits the renderer.", "",
              "### Goals", ""]
    lines += goal_lines(results, sd)
    lines += [
        "", "### How to read this", "",
        "- **Volumes**: `pcvr_native.phantoms.dense_volume(n, seed=1)` (smooth noise, every voxel active) and "
        "`sparse_cloud(n, seed=2)` (thresholded fractal noise, about 15% active), spanning [-1, 1]³.",
        f"- **View**: orthographic, looking along {tuple(st['view_direction'])} with up {tuple(st.get('view_up', ()))} "
        "(oblique: no volume axis is parallel to the view, and none projects parallel to an image axis), framing the "
        "whole volume plus the kernel radius. **m** is the magnification, "
        "pixels per voxel; PCVR's automatic subgrid stride L equals m.",
        "- **Methods**: `regular` splats every footprint at image resolution; `pcvr` splats into the stride-L subgrid and "
        "post-convolves once with a bilinear or gauss1.4 filter; `bilinear spread` puts each voxel's whole footprint "
        "integral on its 2×2 nearest subgrid nodes, then post-convolves (bilinear). Splat kernel: gauss1.4 throughout.",
        f"- **Times** are wall-clock medians of `render_xray` (Python call included) over *runs* repetitions (up to "
        f"{st['reps']}; at least {st['min_reps']} unless one run takes over {st['slow_s']:.0f} s, then fewer, at least 1). "
        "Within a repetition the methods run one after another in an order rotated every repetition, so machine noise "
        "hits all of them alike. **Speed-up** is regular's median over the method's median in the same run. At m = 1 "
        "the stride is 1, so pcvr splats exactly as regular does (and its bilinear post filter is the identity): "
        "differences between their times there are noise, and show how large the noise is.",
        "- **M vox/s**: active voxels per second of render time (the whole render, post-convolution included). "
        "**Cores busy**: the process's CPU time over wall time during the render (median): how many cores the render "
        "actually kept busy; below the core count means serial parts, or other work on the machine taking cores away.",
        "- **Peak MB**: extra resident memory at the render's peak over the process with the grid already built "
        "(measured once per configuration in a fresh child process: VmHWM reset through `/proc/self/clear_refs`, "
        "then read after the render). It includes the returned float32 image.",
        f"- **Accuracy**: `method=\"exact\"` (double precision, analytic footprint per pixel) evaluated at every "
        f"{st['pixel_step']}th pixel in both directions (`pixel_step={st['pixel_step']}`); each method's image is "
        f"compared at the same pixels, `image[::{st['pixel_step']}, ::{st['pixel_step']}]`. {st['pixel_step']} is co-prime "
        "with every stride, so the samples cover all subgrid phases. **rel RMSE** = RMS(method − exact) / RMS(exact); "
        "**PSNR** = 20 log10(max |exact| / RMSE). Empty background pixels (zero in both) are among the samples: they do "
        "not change rel RMSE, but they raise PSNR.",
        "", "### Results", ""]
    for v in results["volumes"]:
        lines += volume_table(v) + [""]
    lines += perspective_section(results) + [""]
    lines += ["### Time versus error (PCVR's methods on the throughput volumes)", "", f"![time versus error]({rel(tve)})", "",
              "Lower left is better. Each line is one method across magnifications 1 to 8 (the numbers at the points).", ""]
    lines += accuracy_notes(results) + [""]
    lines += [
              f"![speed-up versus magnification]({rel(spd)})", ""]
    lines += sol_section(results, sd) + [""]
    lines += limits_section(results, sd) + [""]
    output.write_text("\n".join(lines))
