#!/usr/bin/env python3
"""Blender's volume materials beside Cycles: smoke, fire and a shadowed CT head rendered by PCVR and by Cycles
in the same run, same material, same sun, Cycles at high samples as the reference (issue 22).

| step    | what                                                                                          |
|---------|-----------------------------------------------------------------------------------------------|
| scenes  | blender_materials.py, in a child process with the bpy module: the CT head (96^3, CT Bone preset)   |
|         | in PCVR's Blinn-Phong and scattering-with-shadows shadings, and a 64^3 plume with Blender's Quick  |
|         | Smoke and Quick Fire materials (PCVR with shadows), and the smoke with a `color` grid (Color         |
|         | Attribute); Cycles renders each with the same material at                                           |
|         | SAMPLES samples and at a quarter of them (quick: 48^3 and 32^3 volumes, fewer pixels and samples)   |
| timing  | each render as a whole (bpy.ops.render.render, the file read included); PCVR the least of ROUNDS    |
| error   | PSNR of linear RGB (peak 1) against Cycles at SAMPLES: over the whole frame, and over the volume's    |
|         | pixels (those where either image leaves the world's colour by more than a PNG step, 1/255); the    |
|         | mean luminance over the volume's pixels as a share of Cycles'                                     |
| images  | docs/img/{ct_bone,smoke,fire,coloured_smoke}_{pcvr,cycles}.png, ct_bone_pcvr_scattering.png (quick: under |
|         | out/bench/materials), linked from docs/shaded-rendering-in-blender.md                              |

    python tests/bench/materials_bench.py [--quick]      # prints the section
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
sys.path.append(str(HERE))

from shaded import psnr  # noqa: E402

SAMPLES, QUICK_SAMPLES = 128, 8
ROUNDS, QUICK_ROUNDS = 3, 1
CHILD_TIMEOUT_S = 1800
WORK_DIR = REPO / "out" / "bench" / "materials"
IMAGE_DIR = REPO / "docs" / "img"
# What a reader compares, scene by scene: (scene, variant, label).
ROWS = [("ct_bone", "pcvr", "CT head, CT Bone preset: PCVR's Blinn-Phong (the preset)"),
        ("ct_bone", "pcvr_scattering", "CT head, CT Bone preset: PCVR scattering with shadows"),
        ("ct_bone", "pcvr_scattering_single", "CT head, CT Bone preset: PCVR single scattering with shadows"),
        ("ct_bone", "pcvr_scattering_six", "CT head, CT Bone preset: PCVR scattering, six octaves"),
        ("ct_bone", "pcvr_scattering_ao", "CT head, CT Bone preset: PCVR scattering, ambient occlusion on"),
        ("ct_bone", "pcvr_scattering_no_ao", "CT head, CT Bone preset: PCVR scattering, ambient occlusion off"),
        *((key, variant, f"plume, {material}: PCVR {what}")
          for key, material in (("smoke", "Quick Smoke"), ("fire", "Quick Fire"),
                                ("coloured_smoke", "Quick Smoke with a `color` grid as its Color Attribute"))
          for variant, what in (("pcvr", "scattering with shadows (the default)"),
                                ("pcvr_single", "single scattering"), ("pcvr_six", "six octaves"),
                                ("pcvr_ao", "ambient occlusion on"), ("pcvr_no_ao", "ambient occlusion off"))),
        ("cloud", "pcvr", "cumulus, dense white (density 40), sun: PCVR multiple scattering (the default)"),
        ("cloud", "pcvr_single", "cumulus, sun: PCVR single scattering (one octave)"),
        ("cloud", "pcvr_no_shadows", "cumulus, sun: PCVR without shadows"),
        ("cloud", "pcvr_ao", "cumulus, sun: PCVR, ambient occlusion on"),
        ("cloud", "pcvr_no_ao", "cumulus, sun: PCVR, ambient occlusion off"),
        ("cloud_point", "pcvr", "cumulus, point light: PCVR multiple scattering"),
        ("cloud_point", "pcvr_single", "cumulus, point light: PCVR single scattering"),
        ("cloud_point", "pcvr_ao", "cumulus, point light: PCVR, ambient occlusion on"),
        ("cloud_point", "pcvr_no_ao", "cumulus, point light: PCVR, ambient occlusion off")]
PNG_STEP = 1.0 / 255.0


def job(quick: bool) -> dict:
    # PCVR_MATERIALS_SCENES=cloud,smoke renders only those scenes (in a work folder of their own: runs may overlap).
    scenes = [name for name in os.environ.get("PCVR_MATERIALS_SCENES", "").split(",") if name]
    work_dir = WORK_DIR / "-".join(scenes) if scenes else WORK_DIR
    return {"quick": quick, "samples": QUICK_SAMPLES if quick else SAMPLES, "rounds": QUICK_ROUNDS if quick else ROUNDS,
            "ct_size": 48 if quick else 96, "ct_magnification": 2.0 if quick else 3.0,
            "plume_size": 32 if quick else 64, "plume_pixels": 128 if quick else 256,
            "cloud_size": 48 if quick else 128, "cloud_pixels": (80, 60) if quick else (160, 120),
            "work_dir": str(work_dir), "image_dir": str(work_dir / "img" if quick else IMAGE_DIR),
            "result": str(work_dir / "result.json"), **({"scenes": scenes} if scenes else {}),
            # PCVR_MATERIALS_CYCLES_CACHE=folder keeps Cycles' renders there and reuses them (blender_materials.py)
            **({"cycles_cache": os.environ["PCVR_MATERIALS_CYCLES_CACHE"]}
               if os.environ.get("PCVR_MATERIALS_CYCLES_CACHE") else {})}


def render_in_blender(spec: dict, log) -> dict:
    """Run blender_materials.py on `spec`; its result, or {"error": why}."""
    Path(spec["work_dir"]).mkdir(parents=True, exist_ok=True)
    job_path = Path(spec["work_dir"]) / "job.json"
    job_path.write_text(json.dumps(spec))
    Path(spec["result"]).unlink(missing_ok=True)
    proc = subprocess.Popen([sys.executable, str(HERE / "blender_materials.py"), str(job_path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    watchdog = threading.Timer(CHILD_TIMEOUT_S, proc.kill)  # the progress lines below block until the child ends
    watchdog.start()
    tail = []
    try:
        for line in proc.stderr:
            if line.startswith("[blender "):
                log("  " + line.rstrip())
            tail = (tail + [line.rstrip()])[-3:]
        status = proc.wait()
    finally:
        watchdog.cancel()
    if status != 0 or not Path(spec["result"]).exists():
        return {"error": f"the Blender child exited with status {status}: {' / '.join(tail)[-300:]}"}
    return json.loads(Path(spec["result"]).read_text())


def compare(image, reference, world) -> dict:
    """PSNR of `image` against `reference` (linear RGB, peak 1) over the frame and over the volume's pixels."""
    image, reference = (np.asarray(a, dtype=np.float64)[..., :3] for a in (image, reference))
    background = np.asarray(world, dtype=np.float64)
    volume = ((np.abs(image - background) > PNG_STEP) | (np.abs(reference - background) > PNG_STEP)).any(axis=-1)
    luminance = np.array([0.2126, 0.7152, 0.0722])  # linear Rec. 709
    return {"psnr_frame": psnr(image, reference), "psnr_volume": psnr(image[volume], reference[volume]),
            "volume_pixels": float(volume.mean()),
            "luminance_ratio": float((image[volume] @ luminance).mean() / max((reference[volume] @ luminance).mean(),
                                                                              1e-12))}


def run(quick: bool, log) -> dict:
    spec = job(quick)
    out = render_in_blender(spec, log)
    if "error" in out:
        log(f"  materials: {out['error']}")
        return out
    out.update(samples=spec["samples"], rounds=spec["rounds"], threads=os.cpu_count(), load=os.getloadavg())
    for key, scene in out["scenes"].items():
        variants = scene["variants"]
        reference = np.load(variants["cycles"]["npy"])
        for variant, rec in variants.items():
            if variant != "cycles":
                rec.update(compare(np.load(rec["npy"]), reference, scene["world"]))
                rec["cycles_ratio"] = variants["cycles"]["seconds"] / rec["seconds"]
    for key, variant, label in ROWS:
        if key not in out["scenes"]:
            continue
        rec = out["scenes"][key]["variants"][variant]
        log(f"  {label}: {rec['seconds']:.2f} s, Cycles {rec['cycles_ratio']:.0f}x as long; PSNR "
            f"{rec['psnr_frame']:.1f} dB (frame), {rec['psnr_volume']:.1f} dB (volume); mean luminance "
            f"{rec['luminance_ratio']:.2f} of Cycles' (volume)")
    return out


def section(res: dict | None) -> list[str]:
    if not res:
        return []
    lines = ["## Materials beside Cycles", ""]
    if "error" in res:
        return lines + [f"Not measured: {res['error']}.", ""]
    scenes = res["scenes"]
    ct, plume, cloud = (scenes.get(key, {"width": 0, "height": 0, "voxels": 0}) for key in ("ct_bone", "smoke", "cloud"))
    lines += [
        "The same scene, material and sun rendered by PCVR and by Cycles in one run through the `bpy` module "
        f"(Blender {res['blender']}, {res['threads']} threads, load average {res['load'][0]:.1f} at the end; "
        "`tests/bench/materials_bench.py`): a CT head with the CT Bone preset "
        f"({ct['width']} x {ct['height']} pixels, {ct['voxels']:,} active voxels), a synthetic plume with Blender's "
        f"Quick Smoke and Quick Fire materials ({plume['width']} x {plume['height']} pixels, {plume['voxels']:,} "
        "voxels of smoke) and a dense white cumulus (`tools/cumulus.py`, Principled Volume density 40, colour 0.98, "
        f"anisotropy 0.5; {cloud['width']} x {cloud['height']} pixels, {cloud['voxels']:,} voxels of cloud; Cycles "
        "with 64 volume bounces). Cycles, the reference, renders at "
        f"{res['samples']} samples per pixel with its default denoiser; times are the whole `bpy.ops.render.render` "
        f"(PCVR's the least of {res['rounds']}). PSNR of linear RGB (peak 1) against it, over the frame and over "
        "the volume's pixels (where either image leaves the world's colour by more than 1/255); *Cycles at a "
        "quarter*: Cycles' own image at a quarter of the samples against the reference, for scale. The images: "
        "[docs/shaded-rendering-in-blender.md](shaded-rendering-in-blender.md#against-cycles).", "",
        "| scene | PCVR (s) | Cycles (s) | Cycles / PCVR | PSNR frame (dB) | PSNR volume (dB) | luminance / Cycles' "
        f"| volume pixels | Cycles at {max(1, res['samples'] // 4)} samples: s, PSNR volume (dB) |",
        "|---|---|---|---|---|---|---|---|---|"]
    for key, variant, label in ROWS:
        if key not in scenes:
            continue
        scene = scenes[key]["variants"]
        rec, cycles, quarter = scene[variant], scene["cycles"], scene["cycles_quarter"]
        lines.append(f"| {label} | {rec['seconds']:.2f} | {cycles['seconds']:.1f} | {rec['cycles_ratio']:.0f} "
                     f"| {rec['psnr_frame']:.1f} | {rec['psnr_volume']:.1f} | {rec['luminance_ratio']:.2f} "
                     f"| {100 * rec['volume_pixels']:.0f}% "
                     f"| {quarter['seconds']:.1f}, {quarter['psnr_volume']:.1f} |")
    return lines + [""]


if __name__ == "__main__":
    import standalone
    standalone.main(__doc__, run, section)
