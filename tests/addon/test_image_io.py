"""image_io: OpenImageIO files written whole or not at all."""

import os

import numpy as np
import pytest

from pcvr_addon.io import image_io


@pytest.fixture
def pixels(rng):
    return rng.random((12, 20, 4)).astype(np.float32)


def test_exr_keeps_floats_and_channel_names(tmp_path, pixels):
    values = np.concatenate([pixels, 7.5 * pixels[:, :, :1]], axis=-1)
    image_io.write_image(str(tmp_path / "a.exr"), values, ["R", "G", "B", "A", "XRay"])
    np.testing.assert_array_equal(image_io.read_passes(str(tmp_path / "a.exr"))[""], values)


@pytest.mark.parametrize("extension, levels", [(".png", 255), (".tif", 65535)])
def test_integer_formats_store_straight_srgb_colour(tmp_path, pixels, extension, levels):
    premultiplied = pixels.copy()
    premultiplied[:, :, :3] *= pixels[:, :, 3:]
    premultiplied[0, 0] = 0.0  # fully transparent
    image_io.write_image(str(tmp_path / f"a{extension}"), premultiplied)
    read = image_io.read_passes(str(tmp_path / f"a{extension}"))[""]
    expected = image_io.srgb_encode(pixels[:, :, :3])
    expected[0, 0] = 0.0
    np.testing.assert_allclose(read[:, :, :3], expected, atol=0.51 / levels + 1e-6)
    np.testing.assert_allclose(read[:, :, 3], premultiplied[:, :, 3], atol=0.51 / levels)


def test_replaces_atomically_and_leaves_nothing_on_failure(tmp_path, pixels):
    target = tmp_path / "a.png"
    image_io.write_image(str(target), pixels)
    image_io.write_image(str(target), 1 - pixels)
    assert os.listdir(tmp_path) == ["a.png"]
    with pytest.raises(OSError):
        image_io.write_image(str(tmp_path / "missing" / "a.png"), pixels)
    with pytest.raises(ValueError, match="unsupported"):
        image_io.write_image(str(tmp_path / "a.jpg"), pixels)
    assert os.listdir(tmp_path) == ["a.png"]
