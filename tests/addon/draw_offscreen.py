"""Run as a script by test_viewport_draw.py: draw an image with viewport_draw into an offscreen framebuffer
and save what the GPU made of it.

    python draw_offscreen.py OUTPUT.npz

`bpy` in background mode has no GPU context, and its gpu module says so ("GPU functions for drawing are not
available in background mode") until something initialises the GPU: an EEVEE render does (through EGL,
without a display). The draw then runs from inside a PCVR render, so that the engine whose
bind_display_space_shader it calls is Blender's own, into an offscreen framebuffer set up in region pixels as
a viewport's is. OUTPUT.npz gets `image` (what was drawn), `rect`, `background` and `read` (the framebuffer,
row 0 on top); or `skipped`, the reason no GPU could be had. Without a working EGL (libegl1, libegl-mesa0 and
libgl1-mesa-dri on Debian) Blender aborts while it initialises the GPU: the line READY on stdout tells that
apart from a failure of the draw.
"""

import sys
from pathlib import Path

import bpy
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import pcvr_addon  # noqa: E402
from pcvr_addon import engine as pcvr_engine  # noqa: E402

REGION = (40, 30)
RECT = (8, 4, 24, 18)          # x, y, width, height in region pixels from the bottom left
BACKGROUND = (0.25, 0.5, 0.75, 1.0)
READY = "GPU ready"


def initialise_gpu(scene):
    """Render 8 x 8 pixels with EEVEE, which creates Blender's GPU context. The reason when it cannot."""
    scene.render.engine = next(engine for engine in ('BLENDER_EEVEE_NEXT', 'BLENDER_EEVEE')
                               if engine in scene.render.bl_rna.properties["engine"].enum_items.keys())
    scene.render.resolution_x = scene.render.resolution_y = 8
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    bpy.ops.render.render()
    import gpu
    try:
        gpu.platform.backend_type_get()
    except SystemError as ex:
        return str(ex)
    return None


def pixel_space(width, height):
    """The projection that maps region pixels to the framebuffer, as Blender sets it before view_draw."""
    from mathutils import Matrix
    return Matrix(((2 / width, 0, 0, -1), (0, 2 / height, 0, -1), (0, 0, -1, 0), (0, 0, 0, 1)))


def draw_in_render(image, output):
    """Replace PCVR's F12 render by a draw of `image` into an offscreen framebuffer; save the result."""
    import gpu
    from mathutils import Matrix
    from pcvr_addon.render import viewport_draw

    def render(engine, depsgraph):
        offscreen = gpu.types.GPUOffScreen(*REGION, format='RGBA32F')
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=BACKGROUND)
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_matrix(Matrix.Identity(4))
                gpu.matrix.load_projection_matrix(pixel_space(*REGION))
                viewport_draw.draw(engine, depsgraph.scene, viewport_draw.upload(image), RECT)
            read = framebuffer.read_color(0, 0, *REGION, 4, 0, 'FLOAT')
        pixels = np.array(read.to_list(), dtype=np.float32).reshape(REGION[1], REGION[0], 4)[::-1]
        np.savez(output, image=image, rect=RECT, background=BACKGROUND, read=pixels)
        offscreen.free()

    pcvr_engine.render = render


def main(output):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    pcvr_addon.register()
    scene = bpy.context.scene
    reason = initialise_gpu(scene)
    if reason is not None:
        np.savez(output, skipped=reason)
        return
    print(READY, flush=True)
    rng = np.random.default_rng(7)
    height, width = RECT[3] // 2, RECT[2] // 2           # drawn at twice its size, as a coarse step is
    image = rng.random((height, width, 4), dtype=np.float32)
    image[..., :3] *= image[..., 3:]                     # premultiplied
    draw_in_render(image, output)
    scene.render.engine = 'PCVR'
    bpy.ops.render.render()


if __name__ == "__main__":
    main(sys.argv[1])
