"""Big volumes in Blender: a volume whose voxels take more than the scene's Stream Above (MiB) is not read
whole. In X-ray mode it renders from its file a batch at a time (pcvr_native.GridStream), with the same image;
shaded and MIP modes in bricks composited front to back, at full resolution, also with the same image (the finest
level of detail that fits where bricks cannot serve). F12 shows the voxels splatted and the time left."""

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
from pcvr_addon.render import cache, prepared_scene, statistics
from pcvr_addon.scene import scene_inputs


@pytest.fixture
def big_volume(tmp_path):
    """A 96^3 field (3.4 MiB of values), 1.6 units wide."""
    i = np.indices((96, 96, 96), dtype=np.float32) / 95 * 2 - 1
    values = np.exp(-3 * (i ** 2).sum(axis=0)) * (1 + 0.3 * np.sin(17 * i[0]) * np.cos(11 * i[1]))
    filepath = bs.write_vdb(tmp_path / "big.vdb", values.astype(np.float32), bs.centred(1 / 60, 96))
    return bs.add_volume("Big", filepath, rotation=(0.3, 0.2, 0.5))


def cached_kinds():
    return sorted(type(grid).__name__ for grid in cache.grids.cached())


def test_a_volume_above_the_threshold_renders_streamed_with_the_same_image(big_volume):
    scene = bs.setup(64, 48, method='PCVR')
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.4)
    cache.grids.clear()
    scene.pcvr.stream_above = 1  # MiB
    streamed = bs.xray(bs.render(scene))
    assert cached_kinds() == ["GridStream"]
    mode, stats = statistics.last_render[scene.session_uid]
    assert "| Streamed 1 volume from its file in 1 batch" in statistics.status_line(mode, stats)
    scene.pcvr.stream_above = 4
    whole = bs.xray(bs.render(scene))
    assert cached_kinds() == ["Grid", "GridStream"]
    assert whole.max() > 0
    np.testing.assert_allclose(streamed, whole, rtol=0, atol=1e-6 * whole.max())


def lit_scene(volume, mode):
    import lit_scenes as ls

    scene = ls.shaded_setup(64, 48, method='PCVR', mode=mode, transparent=False)
    bpy.context.view_layer.pcvr.use_pass_xray = True
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=2.4)
    ls.add_light('SUN', rotation=(0.4, 0.3, 0.0), power=3.0)
    ls.set_world((0.2, 0.2, 0.2))
    ls.set_ramp(volume)
    return scene


@pytest.mark.parametrize("mode", ['SHADED', 'MIP'])
def test_shaded_and_mip_render_a_big_volume_at_full_resolution_in_bricks(big_volume, mode):
    """3.4 MiB of voxels under a 1 MiB Stream Above: rendered from its file at full resolution, in bricks of at
    most 1 MiB of values composited front to back (pcvr_native's GridStream renders), as the volume read whole:
    the Combined pass measured 4.8e-6 apart shaded (the lattice each brick samples rounds its coordinates otherwise),
    0 MIP; the bound twice that."""
    import lit_scenes as ls

    scene = lit_scene(big_volume, mode)
    scene.pcvr.stream_above = 4
    whole = ls.combined(bs.render(scene))
    cache.grids.clear()
    scene.pcvr.stream_above = 1
    passes = bs.render(scene)
    assert cached_kinds() == ["GridStream"]
    stats = statistics.last_render[scene.session_uid][1]
    assert stats["level"] == 0 and stats["batches"] > 1
    assert whole[:, :, :3].mean() > 0.1  # lit: the comparison can fail
    np.testing.assert_allclose(ls.combined(passes), whole, rtol=0, atol=1e-5)
    # The XRay pass comes from the stream itself.
    reference = pn.render_xray(pn.read_vdb(big_volume.data.filepath).with_index_to_world(
        np.array(big_volume.matrix_world) @ pn.read_vdb(big_volume.data.filepath).index_to_world), bs.reference_camera(),
        passband=scene.pcvr.passband.lower())
    np.testing.assert_allclose(bs.xray(passes), reference, rtol=0, atol=1e-3 * reference.max())


def test_where_bricks_cannot_serve_the_level_that_fits_stands_in(big_volume):
    """Shadows need every voxel at once: level 1 (0.4 MiB) stands in for the volume, made from its file a batch at
    a time, coarser than the whole: RMS difference of the Combined pass measured 0.0052 (unshadowed), the bound
    twice that."""
    import lit_scenes as ls

    scene = lit_scene(big_volume, 'SHADED')
    scene.pcvr.shadows = True
    scene.pcvr.stream_above = 4
    whole = ls.combined(bs.render(scene))
    cache.grids.clear()
    scene.pcvr.stream_above = 1
    coarse = ls.combined(bs.render(scene))
    assert statistics.last_render[scene.session_uid][1]["level"] == 1
    assert 0 < np.sqrt(np.mean((coarse - whole) ** 2)) < 0.011
    inputs, _display = scene_inputs.read(bpy.context.evaluated_depsgraph_get(), prepared_scene.export_grid)
    warnings = prepared_scene.prepare(inputs).warnings
    assert any("Stream Above, and shadows need every voxel at once: rendered from level 1" in w for w in warnings)


def test_the_threshold_follows_the_memory_available_by_default():
    assert prepared_scene.stream_threshold(None) is None  # shaded and MIP modes
    assert prepared_scene.stream_threshold(0) == pn.default_memory_limit() // 4
    assert prepared_scene.stream_threshold(3) == 3 * prepared_scene.MiB


def test_progress_line_counts_voxels_and_time_left():
    assert statistics.progress_line(0.25, 3.0, 134_200_000) == "Splatting 33.5M of 134.2M voxels | 9 s left"
    assert statistics.progress_line(0.01, 0.5, 134_200_000) == "Splatting 1.3M of 134.2M voxels"  # too early to tell
    assert statistics.progress_line(0.5, 2.0) == "Rendering 50% | 2 s left"
    assert statistics.progress_line(1.0, 4.0) == "Rendering 100%"


class FakeEngine:
    def __init__(self):
        self.progress, self.lines = [], []

    def update_progress(self, fraction):
        self.progress.append(fraction)

    def update_stats(self, stats, info):
        self.lines.append(info)


def test_progress_report_updates_the_bar_every_time_and_the_line_four_times_a_second():
    fake, now = FakeEngine(), [100.0]
    report = statistics.ProgressReport(fake, voxels=1_000_000, clock=lambda: now[0])
    for fraction, time in [(0.1, 100.1), (0.2, 100.2), (0.3, 100.4), (0.5, 101.0)]:
        now[0] = time
        report(fraction)
    assert fake.progress == [0.1, 0.2, 0.3, 0.5]
    assert fake.lines == ["Splatting 0.1M of 1.0M voxels | 1 s left", "Splatting 0.3M of 1.0M voxels | 1 s left",
                          "Splatting 0.5M of 1.0M voxels | 1 s left"]
