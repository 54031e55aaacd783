# SPDX-License-Identifier: GPL-3.0-or-later

"""Images on disk, through the OpenImageIO that Blender bundles (see compat.bundled_module).

| extension     | written as                                                                   |
|---------------|------------------------------------------------------------------------------|
| .exr          | 32-bit float, values as given: linear, colour premultiplied by alpha         |
| .png          | 8-bit, colour divided by alpha (straight alpha) and sRGB-encoded             |
| .tif / .tiff  | 16-bit, colour divided by alpha (straight alpha) and sRGB-encoded            |

Pixels come in as Blender's render results hold them: linear, colour premultiplied by alpha (write_values
stores one channel as it is instead, float or 16-bit, whatever the extension; write_drr a DRR through it). Files
are written next to their destination and renamed into place, so a reader never sees a
half-written image.
"""

import os
import tempfile
import uuid

import bpy
import numpy as np

from .. import compat

FORMATS = {
    ".exr": "float",
    ".png": "uint8",
    ".tif": "uint16",
    ".tiff": "uint16",
}
UINT16_MAX = 65535


def openimageio():
    """The OpenImageIO module; ImportError with what to install where Blender has none (bpy 4.2)."""
    return compat.bundled_module("OpenImageIO", package="openimageio")


def srgb_encode(linear):
    """The sRGB transfer function of values clamped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


COLOUR_CHANNELS = ("R", "G", "B", "Y")


def default_channel_names(count):
    return {1: ["Y"], 2: ["Y", "A"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}.get(
        count, [f"channel{i}" for i in range(count)])


def display_encoded(pixels, channel_names):
    """What integer formats store: straight colour, sRGB-encoded, everything clamped to [0, 1] (which
    OpenImageIO quantises to the integer range)."""
    colour = [index for index, name in enumerate(channel_names) if name in COLOUR_CHANNELS]
    encoded = pixels.copy()
    if "A" in channel_names:
        alpha = pixels[:, :, channel_names.index("A")][:, :, None]
        encoded[:, :, colour] = np.divide(pixels[:, :, colour], alpha, where=alpha > 0,
                                          out=np.zeros_like(pixels[:, :, colour]))
    encoded[:, :, colour] = srgb_encode(encoded[:, :, colour])
    return np.clip(encoded, 0.0, 1.0)


def write_image(filepath, pixels, channel_names=None, description=None):
    """Write `pixels`, float32 (height, width, channels) with row 0 on top, to `filepath`; the
    extension picks the format (see the table above). Channels are named R, G, B, A (or Y, A) unless
    `channel_names` says otherwise; integer formats encode only R, G, B and Y. `description`: the
    file's ImageDescription (every format keeps it), read back by `description_of`."""
    oiio = openimageio()
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    height, width, count = pixels.shape
    channel_names = list(channel_names or default_channel_names(count))
    if len(channel_names) != count:
        raise ValueError(f"{count} channels but {len(channel_names)} channel names")

    extension = os.path.splitext(filepath)[1].lower()
    if extension not in FORMATS:
        raise ValueError(f"'{filepath}': unsupported image format, use one of {', '.join(FORMATS)}")
    pixel_type = FORMATS[extension]
    spec = oiio.ImageSpec(width, height, count, pixel_type)
    spec.channelnames = tuple(channel_names)
    if "A" in channel_names:
        spec.alpha_channel = channel_names.index("A")
    if pixel_type != "float":
        pixels = display_encoded(pixels, channel_names)
        spec.attribute("oiio:UnassociatedAlpha", 1)  # already straight: OpenImageIO must not divide again
    if description is not None:
        spec.attribute("ImageDescription", description)

    _write_atomically(filepath, spec, pixels)


def write_values(filepath, values, pixel_type, channel_name="Y", description=None):
    """Write `values` (height, width), row 0 on top, as one channel stored as they are: `pixel_type` "float"
    (32-bit), or "uint16" (values already whole numbers in 0..65535), whatever the extension's usual type."""
    oiio = openimageio()
    values = np.asarray(values)
    height, width = values.shape
    spec = oiio.ImageSpec(width, height, 1, pixel_type)
    spec.channelnames = (channel_name,)
    if description is not None:
        spec.attribute("ImageDescription", description)
    _write_atomically(filepath, spec, values.astype(np.float32 if pixel_type == "float" else np.uint16)[:, :, None])



def write_drr(filepath, line_integrals, intensity=None, description=None):
    """Write a DRR: the line integrals (float32 (height, width), row 0 on top), or I0 exp(-line integral) with
    `intensity` I0 (16-bit integers, rounded and clipped, where the format holds no floats)."""
    values = np.asarray(line_integrals, dtype=np.float64)
    pixel_type = FORMATS[os.path.splitext(filepath)[1].lower()]
    if intensity is not None:
        values = intensity * np.exp(-values)
        if pixel_type != "float":
            pixel_type = "uint16"
            values = np.clip(np.rint(values), 0, UINT16_MAX)
    elif pixel_type != "float":
        pixel_type = "float"  # a .tif of line integrals: 32-bit float
    write_values(filepath, values, pixel_type, description=description)

def _write_atomically(filepath, spec, pixels):
    """Write `pixels` under `spec` beside `filepath` and rename the file into place."""
    oiio = openimageio()
    extension = os.path.splitext(filepath)[1].lower()
    # Beside the destination, so the rename cannot cross file systems; the extension tells
    # OpenImageIO the format.
    directory, name = os.path.split(os.path.abspath(filepath))
    temporary = os.path.join(directory, f".{name}.{os.getpid()}.{uuid.uuid4().hex[:8]}{extension}")
    try:
        output = oiio.ImageOutput.create(temporary)
        if output is None or not output.open(temporary, spec):
            raise OSError(f"'{filepath}': {oiio.geterror()}")
        ok = output.write_image(pixels)
        ok = output.close() and ok
        if not ok:
            raise OSError(f"'{filepath}': {output.geterror()}")
        os.replace(temporary, filepath)
    except BaseException:
        if os.path.exists(temporary):
            os.remove(temporary)
        raise


def write_passes(filepath, passes, description=None):
    """Write a render's passes {"Combined": RGBA, "Depth"?: Z, "XRay"?: integral} to `filepath`: an .exr holds
    R, G, B, A and the other passes as channels Z and XRay, the other formats the Combined pass."""
    if not filepath.lower().endswith(".exr"):
        write_image(filepath, passes["Combined"], description=description)
        return
    channels, names = [passes["Combined"]], ["R", "G", "B", "A"]
    for pass_name, channel_name in (("Depth", "Z"), ("XRay", "XRay")):
        if pass_name in passes:
            channels.append(passes[pass_name])
            names.append(channel_name)
    write_image(filepath, np.concatenate(channels, axis=-1), channel_names=names, description=description)


def description_of(filepath):
    """The ImageDescription an image was written with, "" when it has none or cannot be read."""
    image = openimageio().ImageInput.open(filepath)
    if image is None:
        return ""
    try:
        return str(image.spec().get_string_attribute("ImageDescription", ""))
    finally:
        image.close()


def read_passes(filepath):
    """The channels of an image grouped by pass: {"Layer.Pass": float32 (height, width, channels)} for
    multi-layer OpenEXR channels named "Layer.Pass.C", {"": ...} for plain R, G, B, A; row 0 on top.
    Values are as stored: integer formats give straight, sRGB-encoded colour in [0, 1]."""
    oiio = openimageio()
    as_stored = oiio.ImageSpec()
    as_stored.attribute("oiio:UnassociatedAlpha", 1)
    image = oiio.ImageInput.open(filepath, as_stored)
    if image is None:
        raise OSError(f"'{filepath}': {oiio.geterror()}")
    channels = {}
    try:
        subimage = 0
        while image.seek_subimage(subimage, 0):
            spec = image.spec()
            pixels = np.asarray(image.read_image("float"), dtype=np.float32)
            pixels = pixels.reshape(spec.height, spec.width, spec.nchannels)
            for index, name in enumerate(spec.channelnames):
                channels[name] = pixels[:, :, index]
            subimage += 1
    finally:
        image.close()

    passes = {}
    for name, values in channels.items():
        passes.setdefault(name.rpartition(".")[0], []).append(values)
    return {name: np.stack(values, axis=-1) for name, values in passes.items()}


def render_result_passes(scene):
    """The passes of Blender's last render ("Render Result"), read back through a temporary multi-layer
    OpenEXR file: {"ViewLayer.Combined": ..., "ViewLayer.XRay": ..., "Composite.Combined": ...}."""
    image = bpy.data.images["Render Result"]
    render = scene.render
    settings = render.image_settings
    saved_format = settings.file_format
    saved = (settings.color_depth, render.pixel_aspect_x, render.pixel_aspect_y)
    directory = tempfile.mkdtemp(prefix="pcvr-")
    filepath = os.path.join(directory, "result.exr")
    try:
        compat.set_file_format(settings, 'OPEN_EXR_MULTILAYER')
        settings.color_depth = '32'
        # Blender 5.0 fails to write multi-part files whose pixel aspect is not 1 ("Conflicting
        # attributes found for header"); the pixels are the same either way.
        render.pixel_aspect_x = render.pixel_aspect_y = 1.0
        image.save_render(filepath, scene=scene)
        return read_passes(filepath)
    finally:
        compat.set_file_format(settings, saved_format)
        settings.color_depth, render.pixel_aspect_x, render.pixel_aspect_y = saved
        if os.path.exists(filepath):
            os.remove(filepath)
        os.rmdir(directory)
