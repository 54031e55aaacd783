"""Seed corpora for the fuzz targets (make fuzz): small .vdb files of every kind pcvr reads or
refuses, written by pcvr_native and by Blender's OpenVDB, and random parameter blocks for the
render targets. Usage: make_corpus.py OUTPUT_DIR (creates OUTPUT_DIR/read_vdb, OUTPUT_DIR/render and
OUTPUT_DIR/shaded)."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

import pcvr_native as pn


def pcvr_files(out: Path):
    rng = np.random.default_rng(1)
    sparse = np.where(rng.random((12, 10, 9)) < 0.2, rng.uniform(0.1, 5.0, (12, 10, 9)), 0.0).astype(np.float32)
    tile = np.zeros((16, 16, 16), np.float32)
    tile[8:16, 0:8, 8:16] = 2.5  # one constant leaf: stored as a tile
    sheared = np.eye(4)
    sheared[:3, :3] = [[0.5, 0.2, 0.0], [0.0, 0.7, -0.1], [0.1, 0.0, 1.2]]
    for compression in ("blosc", "zip", "none"):
        values = sparse if compression != "none" else sparse[:6, :5, :4]  # uncompressed leaves are large
        pn.Grid.from_dense(values, sheared).write_vdb(out / f"pcvr_sparse_{compression}.vdb", compression=compression)
    pn.Grid.from_dense(tile, np.eye(4)).write_vdb(out / "pcvr_tile.vdb")
    micrometres = np.diag([1e-6, 1e-6, 1e-6, 1.0])
    pn.Grid.from_dense(sparse, micrometres).write_vdb(out / "pcvr_world_scale.vdb")  # scale in metadata
    pn.Grid.from_dense(np.zeros((2, 2, 2), np.float32), np.eye(4)).write_vdb(out / "pcvr_empty.vdb")


BLENDER_FILES = """
import bpy
bpy.utils.expose_bundled_modules()
import numpy as np
import openvdb as vdb
out = {out!r}
rng = np.random.default_rng(2)
def grid(cls, name, values):
    g = cls(); g.name = name
    g.copyFromArray(values)
    return g
small = (rng.random((6, 5, 4)) * (rng.random((6, 5, 4)) < 0.5))
vdb.write(out + '/blender_types.vdb', [grid(vdb.FloatGrid, 'density', small.astype(np.float32)),
                                      grid(vdb.DoubleGrid, 'heat', small),
                                      grid(vdb.Int32Grid, 'flags', (small * 10).astype(np.int32)),
                                      grid(vdb.BoolGrid, 'mask', small > 0.5)])
v = vdb.Vec3SGrid(); v.name = 'velocity'; v.copyFromArray(np.ones((3, 3, 3, 3), np.float32))
vdb.write(out + '/blender_vector.vdb', [v])
sphere = vdb.createLevelSetSphere(radius=1.5, center=(0, 0, 0), voxelSize=0.5, halfWidth=1.5)
sphere.name = 'surface'
vdb.write(out + '/blender_level_set.vdb', [sphere])
h = grid(vdb.FloatGrid, 'density', small.astype(np.float32)); h.saveFloatAsHalf = True
vdb.write(out + '/blender_half.vdb', [h])
a = grid(vdb.FloatGrid, 'density', small.astype(np.float32))
b = a.copy(); b.name = 'density'
vdb.write(out + '/blender_instance.vdb', [a, b])
rotated = grid(vdb.FloatGrid, 'density', small.astype(np.float32))
m = np.eye(4); m[:3, :3] = [[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 0.5]]
rotated.transform = vdb.createLinearTransform(m.tolist())
vdb.write(out + '/blender_affine.vdb', [rotated])
"""


def blender_files(out: Path):
    code = textwrap.dedent(BLENDER_FILES.format(out=str(out)))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if proc.returncode != 0:
        print("Blender's OpenVDB files skipped:", proc.stderr[-500:], file=sys.stderr)


def random_blocks(out: Path, seed: int, sizes):
    """Random parameter blocks. FuzzedDataProvider takes every number from the block's end and
    gives zeros once it runs out: short blocks choose the scene and leave the options at their
    first values, long ones choose everything."""
    rng = np.random.default_rng(seed)
    for n, size in enumerate(sizes):
        (out / f"random_{n}.bin").write_bytes(rng.integers(0, 256, size, dtype=np.uint8).tobytes())


def main():
    root = Path(sys.argv[1])
    targets = (("read_vdb", lambda d: (pcvr_files(d), blender_files(d))),
               ("render", lambda d: random_blocks(d, 3, (64, 160, 400, 1000))),
               ("shaded", lambda d: random_blocks(d, 4, (96, 200, 300, 500, 1000, 2000))))
    for name, make in targets:
        directory = root / name
        directory.mkdir(parents=True, exist_ok=True)
        make(directory)
        print(f"{directory}: {len(os.listdir(directory))} seeds")


if __name__ == "__main__":
    main()
