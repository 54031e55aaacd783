"""Esc during a render: render_xray polls the engine's break flag and stops; nothing is written."""

import time

import bpy
import numpy as np
import pcvr_native as pn
import pytest

import blender_scenes as bs
from pcvr_addon import engine as pcvr_engine
from pcvr_addon.io import image_io


def test_break_stops_the_render(tmp_path, monkeypatch):
    scene = bs.setup(96, 96)
    bs.add_camera(location=(0.0, 0.0, 5.0), ortho_scale=1.5)
    bs.add_volume("Dense", bs.write_vdb(tmp_path / "dense.vdb", np.ones((64, 64, 64), dtype=np.float32),
                                        bs.centred(voxel_size=0.02, n=64)))

    # Blender's break flag cannot be raised from a script, so the engine Blender hands to render()
    # gets a stand-in flag that goes up as soon as the native renderer polls it.
    rendering, polls = [False], []
    render_xray = pn.render_xray

    def watched_render_xray(*args, **kwargs):
        rendering[0] = True
        try:
            return render_xray(*args, **kwargs)
        finally:
            rendering[0] = False

    class EscPressed:
        def __init__(self, engine):
            self._engine = engine

        def __getattr__(self, name):
            return getattr(self._engine, name)

        def test_break(self):
            polls.append(rendering[0])
            return rendering[0]

    render = pcvr_engine.render
    monkeypatch.setattr(pn, "render_xray", watched_render_xray)
    monkeypatch.setattr(pcvr_engine, "render", lambda engine, depsgraph: render(EscPressed(engine), depsgraph))

    start = time.perf_counter()
    bpy.ops.render.render(write_still=False)  # returns without an error
    elapsed = time.perf_counter() - start

    assert any(polls), "render_xray never polled the break flag"
    assert elapsed < 5.0
    # Without a result Blender's Render Result holds no image to save.
    with pytest.raises(RuntimeError, match="could not be saved"):
        image_io.render_result_passes(scene)
