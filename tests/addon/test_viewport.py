"""The rendered viewport: what a change renders again, cancelling, re-use, and the image against F12.

The renders are real (pcvr_native on a worker thread); only the final GPU draw is recorded instead of drawn,
and the engine and region are stand-ins (viewport_scenes.py), since `bpy` in background mode has no window.
The draw itself is tested in test_viewport_draw.py.
"""

import bpy
import numpy as np
import pytest

import blender_scenes as bs
import lit_scenes as ls
import viewport_scenes as vs
from pcvr_addon.render import cache, prepared_scene, viewport

SIZE = (96, 64)


@pytest.fixture
def engine():
    engine = vs.StandInEngine()
    yield engine
    engine.free()


@pytest.fixture
def draws(monkeypatch):
    return vs.record_draws(monkeypatch)


@pytest.fixture
def blob_scene(tmp_path, rng):
    """A lumpy volume seen through an orthographic camera a little off its centre: (scene, camera, volume)."""
    scene = bs.setup(*SIZE)
    camera = bs.add_camera(location=(0.3, -0.2, 5.0), ortho_scale=2.0)
    volume = bs.add_volume("Blob", bs.write_vdb(tmp_path / "blob.vdb", bs.blob(rng)))
    return scene, camera, volume


def combined(scene):
    return ls.combined(bs.render(scene))


# -------------------------------------------------------------------------------------------------
# The schedule, on its own

def test_schedule_goes_coarse_to_fine_and_stops_at_full_resolution():
    schedule = viewport.Schedule()
    schedule.restart("XRAY")
    taken = []
    while (job := schedule.take()) is not None:
        taken.append(schedule.steps[job.index].scale)
        schedule.finished(job, seconds=1.0)
    assert taken == [8, 4, 2, 1]
    assert schedule.done and schedule.take() is None


def test_schedule_starts_with_the_finest_quick_step_and_leaves_out_steps_not_worth_it():
    schedule = viewport.Schedule(first_image_seconds=0.05)
    schedule.restart("SHADED")
    for index, seconds in enumerate([0.02, 0.04, 0.09, 0.4]):
        schedule.finished(schedule.take(), seconds)

    schedule.restart("SHADED")
    first = schedule.take()
    assert (first.index, first.first) == (1, True)   # 1/4 takes 40 ms: the finest within 50 ms
    schedule.finished(first, 0.04)
    assert schedule.take().index == 2                 # 1/2 takes 90 ms of full resolution's 400: worth showing

    schedule.seconds[("SHADED", 2)] = 0.3             # now 300 of 400 ms: better go straight to full resolution
    schedule.restart("SHADED")
    schedule.finished(schedule.take(), 0.04)
    assert schedule.take().index == 3


def test_schedule_keeps_timings_per_mode():
    schedule = viewport.Schedule(first_image_seconds=0.05)
    schedule.restart("XRAY")
    while (job := schedule.take()) is not None:
        schedule.finished(job, 0.01)
    schedule.restart("XRAY")
    assert schedule.take().index == 3                 # every X-ray step is quick: full resolution at once
    schedule.restart("SHADED")
    assert schedule.take().index == 0                 # nothing known of shaded: the coarsest first


def test_a_change_cancels_all_but_a_first_image():
    schedule = viewport.Schedule()
    schedule.restart("SHADED")
    first = schedule.take()
    assert not schedule.may_cancel(first)             # the coarsest: it finishes, so motion shows
    schedule.finished(first, 0.2)
    assert schedule.may_cancel(schedule.take())


# -------------------------------------------------------------------------------------------------
# The viewport in Blender

@pytest.mark.parametrize("mode", ['XRAY', 'SHADED', 'MIP'])
@pytest.mark.parametrize("projection", ['ORTHO', 'PERSP'])
def test_full_resolution_equals_the_f12_render(blob_scene, engine, draws, mode, projection):
    scene, camera, volume = blob_scene
    camera.data.type = projection
    camera.data.lens = 80.0
    scene.pcvr.mode = mode
    scene.pcvr.method = 'PCVR'   # with its strides and, in perspective, depth bands
    scene.render.film_transparent = True
    ls.set_ramp(volume)
    ls.add_light('SUN', rotation=(0.6, -0.5, 0.0), power=3.0)
    context = vs.camera_context(camera, *SIZE)

    engine.settle(context)
    image = engine.renderer.latest()
    assert image.step.scale == 1 and image.pixels.shape == (SIZE[1], SIZE[0], 4)
    reference = combined(scene)
    assert reference[..., 3].max() > 0.5, "the test scene shows too little"
    # The same code renders both, with the same camera: measured identical (0.0) in every mode. A tolerance of
    # 1e-6 leaves room for the order in which threads add up a pixel, and none for a camera half a pixel off.
    np.testing.assert_allclose(image.pixels, reference, atol=1e-6)
    texture, rect = draws[-1]
    assert rect == (0, 0, *SIZE) and texture is image.pixels


def test_coarse_images_come_first_and_show_the_same_volume(blob_scene, engine, draws):
    scene, camera, _volume = blob_scene
    context = vs.camera_context(camera, *SIZE)
    shown = []
    engine.update(context)
    renderer = engine.renderer
    renderer_render = renderer._render

    def watched(prepared, view, step, cancel):
        raw = renderer_render(prepared, view, step, cancel)
        shown.append((step.scale, raw["integral"].sum() * step.scale ** 2))
        return raw

    renderer._render = watched
    engine.draw(context)
    assert renderer.wait_until_idle(vs.IDLE_TIMEOUT)
    assert [scale for scale, _total in shown] == [8, 4, 2, 1]
    # Every step integrates the same volume: the image's total per region pixel is the same (measured 0.01% off
    # at 1/2, 0.07% at 1/4, 0.4% at 1/8 where voxels are smaller than pixels); a step whose camera is off by
    # half a pixel, or scaled wrong, loses the volume's edge or counts it twice.
    full = shown[-1][1]
    for scale, total in shown[:-1]:
        assert total == pytest.approx(full, rel=0.01), f"1/{scale}"


def test_step_levels_keep_voxels_within_a_pixel_of_the_step():
    """viewport.step_level: the coarsest level whose voxels span at most LEVEL_PIXELS of the step's pixels, at
    most down to two voxels across; full resolution keeps the render settings' own (None)."""
    coarse, full = viewport.STEPS[0], viewport.STEPS[-1]

    def level(step, pixels_per_voxel, voxels_across=128):
        return viewport.step_level(step, lambda: (pixels_per_voxel, voxels_across))

    assert viewport.LEVEL_PIXELS == 1.0
    assert [level(coarse, m) for m in (2.0, 1.0, 0.6, 0.5, 0.3, 0.25, 0.01)] == [0, 0, 0, 1, 1, 2, 6]
    assert level(coarse, 0.01, voxels_across=16) == 3     # 2 voxels of level 3 across
    assert level(coarse, 0.0) == 0                        # nothing in view
    assert level(full, 0.01) is None


def record_levels(monkeypatch):
    """Record the (image width, level rendered) of every native render: returns the list it appends to."""
    import pcvr_native

    rendered = []
    for name in ("render_xray", "render_shaded", "render_mip"):
        def recorded(grids, camera, *args, native=getattr(pcvr_native, name), **kwargs):
            kwargs["stats"] = {} if kwargs.get("stats") is None else kwargs["stats"]
            result = native(grids, camera, *args, **kwargs)
            rendered.append((camera.width, kwargs["stats"]["level"]))
            return result
        monkeypatch.setattr(pcvr_native, name, recorded)
    return rendered


@pytest.mark.parametrize("mode", ['XRAY', 'SHADED', 'MIP'])
def test_coarse_steps_render_from_coarser_levels_and_full_resolution_from_level_0(blob_scene, engine, draws,
                                                                                  monkeypatch, mode):
    """Zoomed out to 1.5 pixels per voxel at full resolution: the 1/8 step sees 0.19 pixel per voxel and takes
    level 2 (0.75 pixel), 1/4 level 1, 1/2 (0.75 pixel) and full resolution level 0."""
    scene, camera, volume = blob_scene
    camera.data.ortho_scale = 8.0
    scene.pcvr.mode = mode
    ls.set_ramp(volume)
    rendered = record_levels(monkeypatch)
    engine.settle(vs.camera_context(camera, *SIZE))
    assert rendered == [(SIZE[0] // scale, level) for scale, level in zip((8, 4, 2, 1), (2, 1, 0, 0))]


def test_a_streamed_volume_takes_the_coarse_levels_a_volume_read_whole_does(tmp_path, engine, draws, monkeypatch):
    """X-ray of a volume above Stream Above: the steps ask for the same levels (from its box's corners, its
    blocks being in the file), and the coarse ones render the stream's kept levels."""
    scene = bs.setup(*SIZE)
    camera = bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=16.0)
    i = np.indices((96, 96, 96), dtype=np.float32) / 95 * 2 - 1
    bs.add_volume("Field", bs.write_vdb(tmp_path / "field.vdb", np.exp(-3 * (i ** 2).sum(axis=0)).astype(np.float32),
                                        bs.centred(1 / 60, 96)))
    rendered = record_levels(monkeypatch)
    scene.pcvr.stream_above = 4
    engine.settle(vs.camera_context(camera, *SIZE))
    whole = list(rendered)
    rendered.clear()
    cache.grids.clear()
    scene.pcvr.stream_above = 1
    fresh = vs.StandInEngine()  # no step timed yet: it starts from the coarsest step too
    try:
        fresh.settle(vs.camera_context(camera, *SIZE))
    finally:
        fresh.free()
    assert [type(grid).__name__ for grid in cache.grids.cached()] == ["GridStream"]
    assert rendered == whole and whole[0][1] >= 1


def test_a_property_change_renders_again_once(blob_scene, engine, draws):
    scene, camera, _volume = blob_scene
    context = vs.camera_context(camera, *SIZE)
    engine.settle(context)
    renderer = engine.renderer
    started = vs.watch_renders(renderer)
    generation = renderer.schedule.generation

    scene.pcvr.splat_kernel = 'LINEAR'
    engine.settle(context)    # view_update and view_draw, as Blender calls them
    engine.update(context)    # and once more, as for a change elsewhere (the selection)
    engine.draw(context)
    assert renderer.wait_until_idle(vs.IDLE_TIMEOUT)

    # One restart, whose steps go from its first (chosen from the timings so far) to full resolution, once each.
    assert renderer.schedule.generation == generation + 1
    indices = [job.index for job, _view in started]
    assert {job.generation for job, _view in started} == {generation + 1}
    assert indices == sorted(set(indices)) and indices[-1] == len(viewport.STEPS) - 1
    assert renderer.counts["prepares"] == 2
    np.testing.assert_array_equal(renderer.latest().pixels, combined(scene))


def test_a_display_setting_changes_the_image_without_rendering(blob_scene, engine, draws):
    scene, camera, _volume = blob_scene
    context = vs.camera_context(camera, *SIZE)
    engine.settle(context)
    renderer = engine.renderer
    renders, before = renderer.counts["renders"], renderer.latest().pixels

    scene.pcvr.xray_gain = 3.0
    engine.settle(context)

    assert renderer.counts["renders"] == renders
    after = renderer.latest().pixels
    # 1 - exp(-3 I) from 1 - exp(-I): (1 - x)^3 = 1 - y
    np.testing.assert_allclose(1 - (1 - before[..., 0]) ** 3, after[..., 0], atol=1e-5)
    assert len(draws) >= 2 and draws[-1][0] is after


def test_moving_the_view_cancels_the_render_and_starts_again_coarse(tmp_path, engine, draws):
    # A render long enough to be caught running: shaded, thin sheets, 256 x 192.
    scene = ls.shaded_setup(256, 192, method='PCVR')
    scene.pcvr.sheet_spacing = 0.25
    volume = bs.add_volume("Box", bs.write_vdb(tmp_path / "box.vdb", bs.box(n=48, lo=4, hi=44),
                                               bs.centred(voxel_size=0.04, n=48)))
    ls.set_ramp(volume)
    camera = bs.add_camera(location=(1.0, -2.0, 3.0), ortho_scale=2.5)
    camera.rotation_euler = (-camera.location).to_track_quat('-Z', 'Y').to_euler()
    context = vs.camera_context(camera, 256, 192)

    engine.update(context)
    renderer = engine.renderer
    renderer.schedule.first_image_seconds = 0.0   # no step counts as quick: every restart starts coarsest
    started = vs.watch_renders(renderer)
    engine.draw(context)
    while not any(view is not None and job.index == 3 for job, view in started):
        assert renderer.wait_until_idle(0.001) is False, "the full resolution step never started"
    moved = vs.moved(context, 0.2)
    engine.draw(moved)
    assert renderer.wait_until_idle(vs.IDLE_TIMEOUT)

    assert renderer.counts["cancelled"] == 1
    restarted = [job for job, _view in started if job.generation == renderer.schedule.generation]
    assert restarted[0].index == 0 and restarted[0].first
    assert [job.index for job in restarted] == sorted({job.index for job in restarted})
    assert restarted[-1].index == 3
    assert renderer.latest().view == started[-1][1] != started[0][1]


def test_only_a_view_change_reads_nothing_and_prepares_nothing(blob_scene, engine, draws):
    scene, camera, volume = blob_scene
    context = vs.camera_context(camera, *SIZE)
    engine.settle(context)
    renderer = engine.renderer
    assert cache.grids.stats.reads == 1

    for offset in (0.1, 0.2, 0.3):
        engine.settle(vs.moved(context, offset))
    assert (cache.grids.stats.reads, renderer.counts["prepares"]) == (1, 1)

    # Moving the object and changing its density scale prepare again, from the cached grid.
    volume.location.x += 0.1
    engine.settle(context)
    volume.data.pcvr.density_scale = 2.0
    engine.settle(context)
    assert (cache.grids.stats.reads, renderer.counts["prepares"]) == (1, 3)
    np.testing.assert_array_equal(renderer.latest().pixels, combined(scene))


def test_what_does_not_show_renders_nothing(blob_scene, engine, draws):
    scene, camera, volume = blob_scene
    scene.pcvr.mode = 'XRAY'
    context = vs.camera_context(camera, *SIZE)
    engine.settle(context)
    renderer = engine.renderer
    generation = renderer.schedule.generation

    volume.select_set(True)
    ls.add_light('SUN', power=2.0)          # lights do not change an X-ray
    ls.set_ramp(volume)                     # nor do transfer functions
    engine.settle(context)
    assert renderer.schedule.generation == generation

    scene.pcvr.mode = 'SHADED'              # but in shaded mode they do
    engine.settle(context)
    assert renderer.schedule.generation == generation + 1


def test_a_procedural_volume_is_exported_again_only_when_its_geometry_changes(engine, draws, monkeypatch):
    scene = bs.setup(*SIZE)
    camera = bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=3.0)
    cube = bs.add_cube(location=(0.3, 0.2, 0.0))
    volume = bpy.data.objects.new("CubeVolume", bpy.data.volumes.new("CubeVolume"))
    scene.collection.objects.link(volume)
    volume.modifiers.new("Mesh to Volume", 'MESH_TO_VOLUME').object = cube
    exports, export_grid = [], prepared_scene.export_grid
    monkeypatch.setattr(prepared_scene, "export_grid", lambda source: exports.append(source.name) or export_grid(source))
    context = vs.camera_context(camera, *SIZE)

    engine.settle(context)
    engine.settle(vs.moved(context, 0.2))
    assert exports == ["CubeVolume"]

    cube.location.x += 0.5       # the modifier's mesh moves: the volume's geometry changes
    engine.settle(context)
    assert exports == ["CubeVolume"] * 2
    np.testing.assert_array_equal(engine.renderer.latest().pixels, combined(scene))


def test_render_border_in_camera_view_matches_the_f12_border(blob_scene, engine, draws):
    scene, camera, _volume = blob_scene
    scene.render.use_border = scene.render.use_crop_to_border = True
    scene.render.border_min_x, scene.render.border_max_x = 0.25, 0.75
    scene.render.border_min_y, scene.render.border_max_y = 0.5, 1.0
    # Zoomed out: the camera's 96 x 64 frame in the middle of a 192 x 128 region.
    context = vs.camera_context(camera, 192, 128, zoom=0.5)

    engine.settle(context)
    image = engine.renderer.latest()
    reference = combined(scene)
    assert image.pixels.shape == reference.shape == (32, 48, 4)
    np.testing.assert_allclose(image.pixels, reference, atol=1e-6)
    # The frame starts at (48, 32) in the region; the border at a quarter of its width and half its height.
    assert draws[-1][1] == (48 + 24, 32 + 32, 48, 32)


def test_viewport_render_border_is_a_crop_of_the_region(blob_scene, engine, draws):
    view_matrix = np.linalg.inv(np.array(blob_scene[1].matrix_world))
    projection = vs.ortho_projection(1.5, 1.0)
    engine.settle(vs.region_context(view_matrix, projection, 120, 80, 'ORTHO'))
    whole = engine.renderer.latest().pixels

    engine.settle(vs.region_context(view_matrix, projection, 120, 80, 'ORTHO', render_border=(0.25, 0.5, 0.75, 1.0)))
    border = engine.renderer.latest().pixels
    assert draws[-1][1] == (30, 40, 60, 40)
    # Regular splatting: each pixel depends only on its centre, so the border is exactly the crop (rows from the
    # top: region rows 40..80 are image rows 0..40).
    np.testing.assert_allclose(border, whole[0:40, 30:90], atol=1e-6)


def test_preview_pixel_size_renders_fewer_pixels(blob_scene, draws):
    scene, camera, _volume = blob_scene
    engine = vs.StandInEngine(pixel_size=2)
    try:
        engine.settle(vs.camera_context(camera, *SIZE))
        image = engine.renderer.latest()
    finally:
        engine.free()
    assert image.step.scale == 1 and image.pixels.shape == (SIZE[1] // 2, SIZE[0] // 2, 4)
    assert draws[-1][1] == (0, 0, *SIZE)


def test_a_missing_file_shows_in_the_viewport_text(tmp_path, blob_scene, engine, draws):
    scene, camera, _volume = blob_scene
    bs.add_volume("Gone", tmp_path / "missing.vdb")
    engine.settle(vs.camera_context(camera, *SIZE))
    engine.draw(vs.camera_context(camera, *SIZE))
    assert "Volume object 'Gone'" in engine.status and "missing.vdb" in engine.status
    assert engine.renderer.latest() is not None   # the other volume still shows


def test_freeing_the_engine_ends_the_worker(blob_scene, draws):
    _scene, camera, _volume = blob_scene
    engine = vs.StandInEngine()
    engine.settle(vs.camera_context(camera, *SIZE))
    thread = engine.renderer._thread
    engine.free()
    assert not thread.is_alive() and engine.viewport_session is None
