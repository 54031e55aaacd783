"""What the benchmark compares: one table of methods and peers per rendering mode.

Each entry names a runner (``native``: pcvr_native in this process; ``blender`` and ``vtk``: a child
process per volume, see peers/) and the parameters that runner takes. evidence.py (X-ray) and
shaded.py, their plots and reports iterate over whatever the tables hold.

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

# PCVR's native rows render the compensated passband (render_xray's default) unless "passband" says "paper":
# the paper's pair, as the rows before the compensation.
XRAY = [
    Method("pcvr", "PCVR (gauss1.4 + bilinear)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss1.4", "post_filter": "bilinear"}, default=True),
    Method("pcvr_paper", "PCVR (gauss1.4 + bilinear), paper's passband", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss1.4", "post_filter": "bilinear", "passband": "paper"}),
    Method("pcvr_gpost", "PCVR (gauss1.4 + gauss1.4 post)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss1.4", "post_filter": "gauss1.4"}),
    Method("pcvr_g20", "PCVR (gauss2.0 + bilinear)", "pcvr", "native",
           {"method": "pcvr", "splat_kernel": "gauss2.0", "post_filter": "bilinear"}),
    Method("regular", "regular splatting (gauss1.4)", "splatting", "native",
           {"method": "regular", "splat_kernel": "gauss1.4", "post_filter": "bilinear"}),
    Method("regular_paper", "regular splatting (gauss1.4), paper's passband", "splatting", "native",
           {"method": "regular", "splat_kernel": "gauss1.4", "post_filter": "bilinear", "passband": "paper"}),
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

# Shaded (shaded.py): the paper's Fig 10a methods, then the peers with the same transfer function, sun
# and camera. "post_filter" of regular splatting is unused (stride 1).
SHADED = [
    Method("pcvr", "PCVR (Catmull-Rom post)", "pcvr", "native",
           {"method": "pcvr", "post_filter": "catmull_rom"}, default=True),
    Method("pcvr_gpost", "PCVR (gauss1.4 post)", "pcvr", "native", {"method": "pcvr", "post_filter": "gauss1.4"}),
    Method("pcvr_bpost", "PCVR (bilinear post)", "pcvr", "native", {"method": "pcvr", "post_filter": "bilinear"}),
    Method("regular", "regular splatting", "splatting", "native", {"method": "regular", "post_filter": "bilinear"}),
    # Variants of PCVR, at m=4 only (shaded.VARIANT_VIEW): what it takes to meet the shaded targets.
    Method("pcvr_l2", "PCVR (Catmull-Rom post), stride 2", "pcvr", "native",
           {"method": "pcvr", "post_filter": "catmull_rom", "stride": 2, "variant": True}),
    Method("pcvr_bpost_l2", "PCVR (bilinear post), stride 2", "pcvr", "native",
           {"method": "pcvr", "post_filter": "bilinear", "stride": 2, "variant": True}),
    # VTK's fixed-point ray caster with its frame-rate adaptation off (see peers/vtk_shaded.py): sample
    # distance in voxels.
    *[Method(f"vtk_fixed_{st:g}", f"VTK fixed-point, step {st:g}", "vtk", "vtk", {"mapper": "fixed_point", "step": st})
      for st in (1.0, 0.5)],
    # ... and as it comes (AutoAdjustSampleDistances on, its own sample distance): what it trades for speed.
    Method("vtk_fixed_defaults", "VTK fixed-point, its defaults", "vtk", "vtk", {"mapper": "fixed_point", "defaults": True}),
    # Cycles with its denoiser, as a user renders: ray marching (as the X-ray rows) and Blender's default
    # volume mode, null scattering. "slow": seconds even on the quick run's small volume, so it skips them.
    *[Method(f"cycles_s{s}{'_rm' if rm else ''}", f"Cycles {s} spp, {'ray marching' if rm else 'null scattering'}, denoised",
             "cycles", "blender", {"engine": "CYCLES", "samples": s, "denoise": True, "ray_marching": rm, "slow": not rm})
      for s, rm in ((4, True), (16, True), (16, False))],
    # EEVEE: Blender's defaults (8 px tiles, 64 slices) and a finer froxel grid; volumetric shadows on.
    *[Method(f"eevee_t{t}_z{z}", f"EEVEE {t}px tiles, {z} slices", "eevee", "blender",
             {"engine": "EEVEE", "samples": 1, "tile_size": str(t), "slices": z, "slow": t < 8})
      for t, z in ((8, 64), (2, 128))],
]

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
