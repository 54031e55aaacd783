"""pcvr_native and Blender (bpy, with its own OpenVDB 12 and TBB) in one process, in both import orders.

Each check runs in a fresh interpreter: the libraries resolve their shared symbols at import, so only a
fresh process shows what an import order does, and a clash that crashes fails one test, not pytest.
"""

import json

import pytest

from _io_helpers import HAVE_BPY, describe, run_python

pytestmark = pytest.mark.skipif(not HAVE_BPY, reason="bpy is not installed")

SCRIPT = r"""
import json, sys
if {order!r} == "bpy_first":
    import bpy
    import pcvr_native as pn
else:
    import pcvr_native as pn
    import bpy
import numpy as np

bpy.utils.expose_bundled_modules()
import openvdb as vdb

work = {work!r}
result = {{}}
values = np.zeros((16, 16, 16), np.float32)
values[4:12, 4:12, 4:12] = np.linspace(0.5, 1.5, 8, dtype=np.float32)[:, None, None]

# Ours: build, write, read back.
grid = pn.Grid.from_dense(values, np.eye(4))
grid.write_vdb(work + "/ours.vdb")
ours = pn.read_vdb(work + "/ours.vdb")
result["ours_round_trip"] = bool(np.array_equal(ours.to_dense(), values[4:12, 4:12, 4:12]))

# Blender's OpenVDB Python module reads our file...
theirs = vdb.read(work + "/ours.vdb", "density")
copy = np.zeros(values.shape, np.float32)
theirs.copyToArray(copy)
result["blender_module_reads_ours"] = bool(np.array_equal(copy, values))

# ... and writes one that we read.
written = vdb.FloatGrid()
written.name = "density"
written.copyFromArray(values * 2)
written.transform = vdb.createLinearTransform(0.5)
vdb.write(work + "/blender.vdb", written)
back = pn.read_vdb(work + "/blender.vdb")
result["ours_reads_blender_module"] = bool(
    np.array_equal(back.to_dense(), 2 * values[4:12, 4:12, 4:12])
    and np.allclose(back.index_to_world, np.diag([0.5, 0.5, 0.5, 1.0])))

# Blender itself (its C++ OpenVDB) loads our file as a volume object.
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.object.volume_import(filepath=work + "/ours.vdb")
volume = bpy.context.active_object.data
volume.grids.load()
result["blender_loads_ours"] = [g.name for g in volume.grids]

# Render: an orthographic camera looking down -Z at the volume's centre.
if hasattr(pn, "render_xray"):
    world_to_camera = np.eye(4)
    world_to_camera[:3, 3] = [-8.0, -8.0, -40.0]
    left, right, bottom, top, near, far = -10.0, 10.0, -10.0, 10.0, 1.0, 100.0
    projection = np.array([
        [2 / (right - left), 0, 0, -(right + left) / (right - left)],
        [0, 2 / (top - bottom), 0, -(top + bottom) / (top - bottom)],
        [0, 0, -2 / (far - near), -(far + near) / (far - near)],
        [0, 0, 0, 1]])
    image = pn.render_xray(ours, pn.Camera(world_to_camera, projection, 32, 32), method="pcvr")
    result["render_sum"] = float(np.sum(image))
    # Integrals summed over pixels: mass (density x unit voxel volume) / pixel area.
    result["render_expected_sum"] = float(values.sum()) / ((right - left) / 32) ** 2
    result["render_finite"] = bool(np.all(np.isfinite(image)))

print("RESULT " + json.dumps(result), flush=True)
"""


@pytest.mark.parametrize("order", ["bpy_first", "pcvr_first"])
def test_pcvr_native_and_bpy_share_a_process(tmp_path, order):
    proc = run_python(SCRIPT.format(order=order, work=str(tmp_path)))
    assert proc.returncode == 0, describe(proc)
    # OpenVDB's own warnings (in colour, without a line end) may come first on the line.
    lines = [line.partition("RESULT ")[2] for line in proc.stdout.splitlines() if "RESULT " in line]
    assert lines, describe(proc)
    result = json.loads(lines[-1])
    assert result["ours_round_trip"]
    assert result["blender_module_reads_ours"]
    assert result["ours_reads_blender_module"]
    assert result["blender_loads_ours"] == ["density"]
    if "render_sum" in result:
        assert result["render_finite"]
        assert result["render_sum"] > 0
        assert result["render_sum"] == pytest.approx(result["render_expected_sum"], rel=0.05)
