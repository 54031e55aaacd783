"""The viewport's draw on a real GPU context: where the image lands, which way up, scaled and blended.

`bpy` in background mode refuses to draw until an EEVEE render has created its GPU context (Mesa's EGL needs no
display), so draw_offscreen.py does that in a child process of its own, draws from inside a PCVR render with
Blender's engine object, and reads the framebuffer back. Where no GPU context can be had (no EGL: Blender aborts),
the test is skipped with the reason Blender gives.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import draw_offscreen

HERE = Path(__file__).resolve().parent

# The image goes through an RGBA16F texture: 11 significant bits, so a value up to 1 is off by at most 2^-11.
HALF_FLOAT = 2.0 ** -11


def bilinear(image, width, height):
    """`image` (row 0 on top) sampled at the centres of a width x height grid over it, as a GPU samples a
    texture with linear filtering and clamped edges."""
    rows, columns = image.shape[:2]
    y = np.clip((np.arange(height) + 0.5) * rows / height - 0.5, 0, rows - 1)
    x = np.clip((np.arange(width) + 0.5) * columns / width - 0.5, 0, columns - 1)
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    y1, x1 = np.minimum(y0 + 1, rows - 1), np.minimum(x0 + 1, columns - 1)
    fy, fx = (y - y0)[:, None, None], (x - x0)[None, :, None]
    top = image[y0][:, x0] * (1 - fx) + image[y0][:, x1] * fx
    bottom = image[y1][:, x0] * (1 - fx) + image[y1][:, x1] * fx
    return top * (1 - fy) + bottom * fy


def test_draw_puts_the_image_over_its_rectangle(tmp_path):
    output = tmp_path / "draw.npz"
    process = subprocess.run([sys.executable, str(HERE / "draw_offscreen.py"), str(output)],
                             capture_output=True, text=True, timeout=300)
    if process.returncode != 0 and draw_offscreen.READY not in process.stdout:
        last_lines = " / ".join(process.stderr.strip().splitlines()[-2:])
        pytest.skip(f"Blender could not initialise a GPU context (exit status {process.returncode}): {last_lines}")
    assert process.returncode == 0, process.stderr[-3000:]
    result = np.load(output)
    if "skipped" in result:
        pytest.skip(f"no GPU context in background mode: {result['skipped']}")

    image, read, background = result["image"], result["read"], result["background"]
    x, y, width, height = result["rect"]
    region_height = read.shape[0]
    # Region rows run bottom up from y; `read` has row 0 on top.
    inside = np.zeros(read.shape[:2], dtype=bool)
    inside[region_height - y - height:region_height - y, x:x + width] = True

    np.testing.assert_array_equal(read[~inside], np.broadcast_to(background, read[~inside].shape))
    drawn = read[inside].reshape(height, width, 4)
    source = bilinear(image, width, height)
    # Premultiplied over the background.
    expected = source + (1 - source[..., 3:]) * background
    np.testing.assert_allclose(drawn, expected, atol=4 * HALF_FLOAT)
