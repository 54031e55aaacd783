"""Slicing rings: the terraces a sharp transfer function shows where a surface crosses the sheets (or a ray
caster's sample planes), measured on a sphere behind a step transfer function; part of ct_head.py's run.

| step        | what                                                                                         |
|-------------|----------------------------------------------------------------------------------------------|
| volume      | a ball of radius 0.4 n in an n^3 grid of 1 mm voxels (n = 96; quick 64): density 1 inside, 0  |
|             | outside, a linear edge one voxel wide (its 0.5 level on the sphere of radius 0.4 n)           |
| transfer    | a step: transparent below 0.49, white and opaque (opacity 1 per voxel) above 0.51; ct_head.py's |
| function    | sun and Blinn-Phong material                                                                 |
| view        | ct_head.py's: 512^2, perspective, 30 degree field of view, the ball in the middle            |
| renders     | `pcvr` with its defaults; `pcvr` with sheets 2 voxels apart (coarser slicing: the control     |
|             | that shows the measure sees rings); VTK's fixed-point mapper at 1 voxel; the reference:       |
|             | `raycast` at steps of REFERENCE_SPACING voxel, every pixel                                   |
| measure     | rings: D = L - L_ref, L the Rec. 709 luminance of premultiplied RGB, where both alphas exceed |
|             | 0.99; D averaged over each 1-pixel annulus about the ball's image centre (the rings are      |
|             | concentric there: the sheets face the camera, so a surface's crossings are circles about the |
|             | view axis); a degree-4 polynomial in the radius fitted to those means and removed (smooth    |
|             | differences of shading are not rings); the RMS and the largest magnitude of what is left, in  |
|             | 8-bit steps (1/255) of luminance                                                             |
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

SIZE, QUICK_SIZE = 96, 64
RADIUS = 0.4          # of the grid's side
SIDE = 512
REFERENCE_SPACING = 0.1  # as ct_head.py; against steps of 0.05 the measure of 0.1 is 0.06 / 255
FIT_DEGREE = 4
OPAQUE = 0.99
STEP_TF = {"density": [0.0, 0.49, 0.51, 1.0],
           "rgba": [[1, 1, 1, 0], [1, 1, 1, 0], [1, 1, 1, 1], [1, 1, 1, 1]], "unit_distance": 1.0}
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
CONTROL_SHEET_SPACING = 2.0


def ball(n: int):
    """(values [i, j, k], index_to_world): the ball, 1 mm voxels, centred in the grid."""
    centre = (n - 1) / 2.0
    i = np.arange(n, dtype=np.float32) - centre
    r = np.sqrt(i[:, None, None] ** 2 + i[None, :, None] ** 2 + i[None, None, :] ** 2)
    return np.clip(RADIUS * n + 0.5 - r, 0.0, 1.0).astype(np.float32), np.eye(4)


def run(quick: bool, workdir: Path, log) -> dict:
    import pcvr_native as pn

    import ct_head
    import peers
    import views
    n = QUICK_SIZE if quick else SIZE
    values, index_to_world = ball(n)
    grid = pn.Grid.from_dense(values, index_to_world, background=0.0)
    workdir.mkdir(parents=True, exist_ok=True)
    vdb = workdir / "ball.vdb"
    grid.write_vdb(str(vdb), "density")
    view = views.perspective(values.shape, index_to_world, square=SIDE, fov_degrees=ct_head.FIELD_OF_VIEW)
    cam, spec = views.camera(view), ct_head.scene_for(STEP_TF)
    reference, reference_s, _ = ct_head.native_render(grid, cam, spec, "raycast", sheet_spacing=REFERENCE_SPACING)
    out = {"size": n, "side": SIDE, "reference_spacing": REFERENCE_SPACING, "reference_s": reference_s, "methods": {}}
    renders = {"`pcvr`": {}, f"`pcvr`, sheets {CONTROL_SHEET_SPACING:g} voxels apart": {"sheet_spacing": CONTROL_SHEET_SPACING}}
    for key, kw in renders.items():
        image, seconds, _ = ct_head.native_render(grid, cam, spec, "pcvr", **kw)
        out["methods"][key] = dict(ring_profile(image, reference), seconds=seconds)
    job = {"mode": "shaded", "vdb": str(vdb), "views": {"p": view}, "scene": spec, "budget_s": 300.0,
           "configs": [{"key": ct_head.VTK_KEY, "mapper": "fixed_point", "step": ct_head.VTK_STEP}],
           "projections": {"p": views.matrices(view)[1].tolist()}}
    peer = peers.run("vtk", job, workdir / "vtk", timeout_s=600, log=log)[ct_head.VTK_KEY, "p"]
    out["methods"]["VTK step 1"] = ({"skipped": peer["skipped"]} if "skipped" in peer else
                                    dict(ring_profile(np.load(peer["image"]), reference), seconds=min(peer["seconds"])))
    log("rings: " + ", ".join(f"{k} {m['rms']:.2f} / {m['peak']:.2f}" for k, m in out["methods"].items() if "rms" in m))
    return out


def ring_profile(image, reference) -> dict:
    """The ring measure of `image` against `reference` (premultiplied RGBA, the ball in the middle)."""
    image, reference = np.asarray(image, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    h, w = reference.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    radius = np.hypot(x - (w - 1) / 2.0, y - (h - 1) / 2.0).astype(int)
    both = (image[..., 3] > OPAQUE) & (reference[..., 3] > OPAQUE)
    difference = (image[..., :3] - reference[..., :3]) @ LUMINANCE
    counts = np.bincount(radius[both], minlength=radius.max() + 1)
    sums = np.bincount(radius[both], weights=difference[both], minlength=radius.max() + 1)
    rings = np.nonzero(counts)[0]
    means = sums[rings] / counts[rings]
    left = means - np.polyval(np.polyfit(rings, means, FIT_DEGREE), rings)
    return {"rms": 255.0 * float(np.sqrt(np.mean(left ** 2))), "peak": 255.0 * float(np.abs(left).max()),
            "radii": int(len(rings)), "pixels": int(both.sum())}


def section(res: dict | None) -> list[str]:
    """The rings' sub-section of ct_head.py's section, or nothing where they were not measured."""
    if not res:
        return []
    lines = ["### Slicing rings on a sphere", "",
             f"A ball of radius {RADIUS * res['size']:g} voxels in a {res['size']}^3 grid behind a step transfer function "
             "(transparent below half its density, opaque white above), lit as above, "
             f"{res['side']}^2 with a 30 degree field of view. The measure: the luminance of each image minus the ray caster's "
             f"(steps of {res['reference_spacing']} voxel) where both are opaque, averaged over each one-pixel annulus about "
             "the ball's centre (the sheets face the camera, so their crossings with the sphere are circles about it), less "
             f"a degree-{FIT_DEGREE} polynomial fit in the radius (smooth shading differences are not rings); RMS and "
             "largest magnitude of the rest in 8-bit steps (1/255). Sheets twice as far apart are the control: the measure "
             "has to rise there.", "",
             "| renderer | rings RMS (1/255) | largest (1/255) | annuli | time (s) |", "|---|---|---|---|---|"]
    lines += [f"| {key} | skipped: {m['skipped']} | | | |" if "skipped" in m else
              f"| {key} | {m['rms']:.2f} | {m['peak']:.2f} | {m['radii']} | {m['seconds']:.3f} |" for key, m in res["methods"].items()]
    return lines + [""]
