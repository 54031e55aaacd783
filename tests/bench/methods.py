"""What the benchmark compares: one table of methods and peers per rendering mode.

Each entry names a runner (``native``: pcvr_native in this process; ``blender`` and ``vtk``: a child
process per volume, see peers/) and the parameters that runner takes. Adding the shaded rows is
adding a ``"shaded"`` list here plus a ``render_shaded`` branch in each runner; evidence.py,
the plots and the report iterate over whatever the table holds.

Peer configurations form a ladder from cheap and rough to slow and accurate, so the time-versus-
error plot shows each peer's whole curve. A peer render whose predicted time (its time on the
previous, smaller view of the same volume, scaled by the pixel count) exceeds ``PEER_BUDGET_S`` is
skipped and reported as such.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Method:
    key: str
    label: str
    family: str            # colour group in the plots: pcvr, splatting, cycles, eevee, vtk
    runner: str            # native, blender, vtk
    params: dict = field(default_factory=dict)
    default: bool = False  # PCVR's shipped defaults: the row the headline compares


PCVR_DEFAULT = "pcvr"

XRAY = [
    Method("pcvr", "PCVR (gauss1.4 + bilinear)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss1.4", "post_filter": "bilinear"}, default=True),
    Method("pcvr_gpost", "PCVR (gauss1.4 + gauss1.4 post)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss1.4", "post_filter": "gauss1.4"}),
    Method("pcvr_g20", "PCVR (gauss2.0 + bilinear)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss2.0", "post_filter": "bilinear"}),
    Method("regular", "regular splatting (gauss1.4)", "splatting", "native",
           {"method": "regular", "splat_kernel": "gauss1.4", "post_filter": "bilinear"}),
    Method("bilinear_spread", "bilinear spreading", "splatting", "native",
           {"method": "bilinear_spread", "splat_kernel": "gauss1.4", "post_filter": "bilinear"}),
    # Cycles: ray marching; (samples per pixel, step rate): step = rate x Cycles' voxel-size estimate.
    *[Method(f"cycles_s{s}_r{r:g}", f"Cycles {s} spp, step rate {r:g}", "cycles", "blender",
             {"engine": "CYCLES", "samples": s, "step_rate": r})
      for s, r in ((1, 1.0), (4, 0.5), (16, 0.25))],
    # EEVEE: froxel grid of tile_size pixels x slices depth slices over the volume's depth range.
    *[Method(f"eevee_t{t}_z{z}", f"EEVEE {t}px tiles, {z} slices", "eevee", "blender",
             {"engine": "EEVEE", "samples": 1, "tile_size": str(t), "slices": z})
      for t, z in ((2, 128), (1, 256))],
    # VTK: sample distance in voxels.
    *[Method(f"vtk_gpu_{st:g}", f"VTK GPU ray cast, additive, step {st:g}", "vtk", "vtk",
             {"mapper": "gpu_additive", "step": st}) for st in (1.0, 0.25)],
    *[Method(f"vtk_fixed_{st:g}", f"VTK fixed-point, step {st:g}", "vtk", "vtk",
             {"mapper": "fixed_point", "step": st}) for st in (1.0, 0.25)],
]

# Shaded and MIP rows join when pcvr_native.render_shaded / render_mip land (see the report's
# "Shaded mode" section for what each runner needs).
SHADED: list[Method] = []

MODES = {"xray": XRAY, "shaded": SHADED}

FAMILIES = {
    "pcvr": ("PCVR", "tab:blue"),
    "splatting": ("other splatting", "tab:gray"),
    "cycles": ("Cycles (CPU)", "tab:red"),
    "eevee": ("EEVEE (llvmpipe)", "tab:green"),
    "vtk": ("VTK (CPU / llvmpipe)", "tab:purple"),
}

PEER_BUDGET_S = 25.0
PEER_BUDGET_QUICK_S = 4.0
