# SPDX-License-Identifier: GPL-3.0-or-later

"""Drawing the viewport's image: the only code that needs Blender's `gpu` module, and with it a GPU context
(which Blender has while it draws a viewport; `blender --background` has none unless something has rendered
with EEVEE first). Imported by view_draw only.

The viewport draws a render engine into a scene-linear buffer and applies the scene's view transform, look,
exposure and gamma itself when it shows that buffer, so the image goes in as linear premultiplied RGBA, drawn
with the shader that RenderEngine.bind_display_space_shader binds (Blender's builtin image shader).
"""

import gpu
import numpy as np
from gpu_extras.presets import draw_texture_2d

# The largest value that rounds to a finite half float (65504): textures are RGBA16F, as Cycles' display is.
HALF_MAX = 65519.0


def upload(pixels):
    """A GPUTexture of `pixels`, float32 (height, width, 4) with row 0 on top."""
    height, width = pixels.shape[:2]
    # Textures start with the bottom row.
    rows = np.clip(np.nan_to_num(pixels[::-1]), -HALF_MAX, HALF_MAX)
    data = np.ascontiguousarray(rows, dtype=np.float32).ravel()
    return gpu.types.GPUTexture((width, height), format='RGBA16F', data=gpu.types.Buffer('FLOAT', data.size, data))


class ImageTexture:
    """The texture of the latest ViewportImage, uploaded once per image."""

    def __init__(self):
        self._serial = None
        self._texture = None

    def of(self, image):
        if image.serial != self._serial:
            self._texture, self._serial = upload(image.pixels), image.serial
        return self._texture


def draw(engine, scene, texture, rect):
    """Draw `texture` over `rect` (x, y, width, height in region pixels from the bottom left), blended over
    what is there (premultiplied alpha)."""
    x, y, width, height = rect
    # The image lies over the whole rectangle: no depth to test against (a depth test left on by an earlier
    # draw, as after EEVEE in Blender 4.2, would hide it).
    depth_test = gpu.state.depth_test_get()
    gpu.state.depth_test_set('NONE')
    gpu.state.blend_set('ALPHA_PREMULT')
    engine.bind_display_space_shader(scene)
    draw_texture_2d(texture, (x, y), width, height)
    engine.unbind_display_space_shader()
    gpu.state.blend_set('NONE')
    gpu.state.depth_test_set(depth_test)
