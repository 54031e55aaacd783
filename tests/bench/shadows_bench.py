#!/usr/bin/env python3
"""Shadows: what render_shaded(shadows=True) costs against the same render without, and how near it stays to
the ray caster's shadow rays (issue 22).

| step      | what                                                                                         |
|-----------|----------------------------------------------------------------------------------------------|
| volumes   | the CT phantom 256^3 (shaded.py's bone-like scene and sun) and ct_head_data's real CT head   |
|           | (ct_head.py's "bone" and "translucent" scenes and sun); quick: the phantom at 64^3, no head   |
| view      | a square perspective image the volume fills (views.perspective), 1024 pixels (quick: 256)    |
| timing    | `pcvr`, 2 threads, shadows off and on in ROUNDS alternating rounds; least wall seconds each;  |
|           | the shadowed render's own seconds building the light's transmittance volume (stats)          |
| error     | PSNR (RGBA, peak 1) of each against the ray caster with the same shadows, every REFERENCE_STEP-th |
|           | pixel (a prime: every subgrid phase), REFERENCE_SPACING voxels per step along view and shadow |
|           | rays; and of the ray caster with shadows against without (what the shadows change)          |

    python tests/bench/shadows_bench.py [--quick]      # prints the section
"""

from __future__ import annotations

import sys
import time
from pathlib import Path


HERE = Path(__file__).resolve().parent
sys.path.append(str(HERE))

import ct_head  # noqa: E402
import ct_head_data  # noqa: E402
import shaded  # noqa: E402
import views  # noqa: E402
from shaded import psnr  # noqa: E402

THREADS = 2
ROUNDS, QUICK_ROUNDS = 3, 1
SQUARE, QUICK_SQUARE = 1024, 256
# The ray caster marches a shadow ray from every lit sample: 0.5 voxel steps and every 31st pixel keep it to
# minutes (on the phantom 0.5 and 0.25 agree to within 0.3 dB of pcvr's PSNR against them).
REFERENCE_SPACING = 0.5
REFERENCE_STEP = 31


def scenes(quick: bool, log) -> dict:
    """{name: (grid, shape, index_to_world, scene spec)}."""
    import pcvr_native as pn
    from pcvr_native import phantoms
    n = shaded.QUICK_SIZE if quick else shaded.SIZE
    ph = phantoms.ct_phantom(n)
    out = {f"CT phantom {n}^3": (pn.Grid.from_dense(ph.values, ph.index_to_world), ph.values.shape, ph.index_to_world,
                                 shaded.SCENE)}
    if quick:
        return out
    try:
        values, index_to_world, _meta = ct_head_data.load()
    except ct_head_data.Unavailable as e:
        log(f"shadows: the CT head is unavailable ({e})")
        return out
    head = pn.Grid.from_dense(values, index_to_world, background=ct_head_data.AIR_HU)
    for tf_key in ct_head.TRANSFER_FUNCTIONS:
        out[f"CT head, {tf_key}"] = (head, values.shape, index_to_world, ct_head.scene(tf_key))
    return out


def render(grid, cam, spec, shadows, stats, **kw):
    import pcvr_native as pn
    return pn.render_shaded(grid, cam, pn.TransferFunction(**spec["transfer_function"]), lights=[pn.Light.sun(**spec["sun"])],
                            ambient=tuple(spec["ambient"]), shading=pn.Shading(**spec["shading"]), threads=THREADS,
                            stats=stats, shadows=shadows, **kw)


def run(quick: bool, log) -> dict:
    rounds = QUICK_ROUNDS if quick else ROUNDS
    square = QUICK_SQUARE if quick else SQUARE
    out = {"threads": THREADS, "square": square, "reference_spacing": REFERENCE_SPACING, "reference_step": REFERENCE_STEP,
           "scenes": {}}
    for name, (grid, shape, xf, spec) in scenes(quick, log).items():
        cam = views.camera(views.perspective(shape, xf, square=square))
        best = {}
        for r in range(rounds):
            for shadows in (False, True) if r % 2 == 0 else (True, False):
                stats: dict = {}
                t0 = time.perf_counter()
                image = render(grid, cam, spec, shadows, stats)
                seconds = time.perf_counter() - t0
                if shadows not in best or seconds < best[shadows][0]:
                    best[shadows] = (seconds, stats, image)
        t0 = time.perf_counter()
        references = {shadows: render(grid, cam, spec, shadows, {}, method="raycast", sheet_spacing=REFERENCE_SPACING,
                                      pixel_step=REFERENCE_STEP) for shadows in (False, True)}
        reference_seconds = time.perf_counter() - t0
        rec = out["scenes"][name] = {"reference_seconds": reference_seconds,
                                     "psnr_shadow_effect": psnr(references[True], references[False])}
        for shadows, (seconds, stats, image) in best.items():
            rec["on" if shadows else "off"] = {
                "seconds": seconds, "seconds_shadows": stats.get("seconds_shadows", 0.0),
                "shadow_texels": stats.get("shadow_texels", 0),
                "psnr_raycast": psnr(image[::REFERENCE_STEP, ::REFERENCE_STEP], references[shadows])}
        rec["ratio"] = rec["on"]["seconds"] / rec["off"]["seconds"]
        log(f"  shadows {name}: off {rec['off']['seconds']:.3f} s, on {rec['on']['seconds']:.3f} s ({rec['ratio']:.2f}x, "
            f"volume {rec['on']['seconds_shadows']:.3f} s); PSNR {rec['off']['psnr_raycast']:.1f} / {rec['on']['psnr_raycast']:.1f} dB")
    return out


def section(res: dict | None) -> list[str]:
    if not res:
        return []
    lines = ["## Shadows", "",
             f"`render_shaded(shadows=True)` against the same render without, {res['square']} x {res['square']} perspective, "
             f"`pcvr`, {res['threads']} threads, least wall seconds of alternating rounds; *volume*: the shadowed render's "
             "seconds building the sun's transmittance volume (its texels beside). PSNR (RGBA) against the ray caster "
             f"with the same shadows (shadow rays per sample), {res['reference_spacing']} voxel steps, one pixel in "
             f"{res['reference_step']} along each axis; *shadow effect*: the ray caster with shadows against without "
             "(lower: the shadows change more).", "",
             "| scene | off (s) | on (s) | on / off | volume (s) | texels | PSNR off (dB) | PSNR on (dB) | shadow effect (dB) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, r in res["scenes"].items():
        lines.append(f"| {name} | {r['off']['seconds']:.3f} | {r['on']['seconds']:.3f} | {r['ratio']:.2f} "
                     f"| {r['on']['seconds_shadows']:.3f} | {r['on']['shadow_texels']:,} | {r['off']['psnr_raycast']:.1f} "
                     f"| {r['on']['psnr_raycast']:.1f} | {r['psnr_shadow_effect']:.1f} |")
    return lines


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
