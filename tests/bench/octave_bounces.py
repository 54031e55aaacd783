"""How many scattering octaves match Cycles at how many volume bounces: one of blender_materials.py's scenes
rendered by Cycles at each bounce count and by PCVR at each octave count (the add-on's other settings as set up
by default), PSNR of linear RGB (peak 1) over the frame / the volume's pixels, and the mean luminance over the
volume as a share of Cycles'. Chose scene_inputs.MOST_SCENE_OCTAVES and the 1 + bounces mapping
(docs/shaded-rendering-in-blender.md, "Clouds: multiple scattering"). Run with the bpy module:

    python tests/bench/octave_bounces.py smoke 128 0,1,2,64 1,2,3,4,6     # scene, samples, bounces, octaves

Cycles' images are kept under out/bench/octave_bounces and reused (the scene's make-up is not in their names).
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import blender_materials as bm  # noqa: E402
from materials_bench import compare, job  # noqa: E402

CACHE = HERE.parents[1] / "out" / "bench" / "octave_bounces"


def main(scene_key, samples, bounces, octaves):
    spec = job(quick=False)
    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as directory:
        scene, _, variants = bm.SCENES[scene_key](spec, directory)
        volume = next(o for o in scene.objects if o.type == 'VOLUME')
        world = bm.lighting.world_colour(scene.world)
        pcvr = {}
        for n in octaves:
            variants["pcvr"]()
            volume.data.pcvr.scattering_octaves = n
            pcvr[n], _ = bm.timed_render(scene)
        for b in bounces:
            path = CACHE / f"{scene_key}_b{b}_{samples}spp_{scene.render.resolution_x}x{scene.render.resolution_y}.npy"
            if not path.exists():
                variants["cycles"]()
                scene.cycles.samples, scene.cycles.volume_bounces = samples, b
                scene.cycles.max_bounces = max(b, scene.cycles.max_bounces)
                start = time.perf_counter()
                image, _ = bm.timed_render(scene)
                np.save(path, np.asarray(image, dtype=np.float32))
                print(f"Cycles at {b} bounces: {time.perf_counter() - start:.1f} s", flush=True)
            reference = np.load(path)
            cells = []
            for n in octaves:
                rec = compare(pcvr[n], reference, world)
                cells.append(f"{n} octaves {rec['psnr_frame']:.1f} / {rec['psnr_volume']:.1f} dB, "
                             f"{rec['luminance_ratio']:.2f}")
            print(f"{scene_key}, Cycles at {b} bounces: " + " | ".join(cells), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), [int(b) for b in sys.argv[3].split(",")],
         [int(n) for n in sys.argv[4].split(",")])
