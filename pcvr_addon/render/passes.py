# SPDX-License-Identifier: GPL-3.0-or-later

"""The finish stage and the render result: native results turned into Blender's passes, and written into the
render result.

Passes: Combined always; Depth in shaded mode with the view layer's Z pass (where opacity first reaches one
half; background 1e10, as Cycles writes it); XRay with the view layer's PCVR X-ray pass, in every mode.
"""

import numpy as np

from .prepared_scene import control_points, density_range

# Depth where a ray meets nothing opaque enough: what Cycles and Workbench write for the background.
BACKGROUND_DEPTH = 1e10


def list_render_passes(scene, view_layer):
    """The passes of a render: (name, channel ids, channel type)."""
    yield ("Combined", "RGBA", 'COLOR')
    if scene.pcvr.mode == 'SHADED' and view_layer.use_pass_z:
        yield ("Depth", "Z", 'VALUE')
    if view_layer.pcvr.use_pass_xray:
        yield ("XRay", "X", 'VALUE')


def register_passes(engine, scene, view_layer):
    for name, channel_ids, channel_type in list_render_passes(scene, view_layer):
        engine.register_pass(scene, view_layer, name, len(channel_ids), channel_ids, channel_type)


def pass_pixels(gain, film_transparent, integral):
    """The pixels of every pass from the line integral: {name: float32 (height, width, channels)}."""
    height, width = integral.shape
    combined = np.empty((height, width, 4), dtype=np.float32)
    # A negative integral (a field with negative values: raw Hounsfield units, air and fat below 0) attenuates
    # nothing: 0, not a negative Combined that reaches -inf where exp overflows. The XRay pass keeps it as it is.
    # (fmax: a NaN integral, too, shows 0.)
    combined[:, :, :3] = (-np.expm1(-gain * np.fmax(integral, np.float32(0.0))))[:, :, None]
    combined[:, :, 3] = (integral != 0) if film_transparent else 1.0
    return {"Combined": combined, "XRay": integral[:, :, None]}


def over_background(rgba, world, film_transparent):
    """Premultiplied `rgba` over the world colour, or as it is with a transparent film."""
    if film_transparent:
        return rgba
    combined = rgba.copy()
    # Channel by channel: one broadcast over the interleaved (height, width, 3) view took 30 ms at 1280 x 720,
    # a third of a full-resolution viewport image; these loops take 8.
    transmitted = np.float32(1.0) - rgba[:, :, 3]
    for channel in range(3):
        combined[:, :, channel] += transmitted * np.float32(world[channel])
    combined[:, :, 3] = 1.0
    return combined


def mip_colours(maximum, points, density_range, mip_color, background=0.0):
    """Premultiplied RGBA of a volume's MIP: through the transfer function's colours (ControlPoints), or grey
    from black at the low end of its density range to white at the high end; alpha 1 where a voxel reaches
    (the maximum is not the grid's scaled background, which rays that meet no voxel return)."""
    reached = maximum != np.float32(background)
    if mip_color == 'GREYSCALE':
        low, high = density_range
        rgb = np.repeat(np.clip((maximum - low) / (high - low), 0.0, 1.0)[:, :, None], 3, axis=2)
    else:
        rgb = points.colour_at(maximum)[:, :, :3]
    rgba = np.concatenate([rgb * reached[:, :, None], reached[:, :, None]], axis=2)
    return rgba.astype(np.float32)


# Automatic exposure: the gain that shows this percentile of the pixels the volumes reach at this grey. 80% keeps
# headroom and midtones: at 95% a CT head's median pixel showed 88% grey, at 80% 68% (the DRR of tools/ct_head.py).
EXPOSURE_PERCENTILE = 99.0
EXPOSURE_GREY = 0.8


def automatic_gain(integral, fallback):
    """The gain with which the EXPOSURE_PERCENTILE-th percentile of the positive integrals shows EXPOSURE_GREY in
    the Combined pass (1 - exp(-gain * integral)); `fallback` when no pixel is positive."""
    reached = integral[integral > 0]
    if reached.size == 0:
        return fallback
    return float(-np.log1p(-EXPOSURE_GREY) / np.percentile(reached, EXPOSURE_PERCENTILE))


def _finish_xray(display, raw):
    integral = raw["integral"]
    gain = automatic_gain(integral, display.xray_gain) if display.auto_exposure else display.xray_gain
    return pass_pixels(gain, display.film_transparent, integral)


def _finish_shaded(display, raw):
    pixels = {"Combined": over_background(raw["rgba"], display.world, display.film_transparent)}
    if raw["depth"] is not None:
        depth = raw["depth"]
        pixels["Depth"] = np.where(np.isfinite(depth), depth, BACKGROUND_DEPTH).astype(np.float32)[:, :, None]
    return pixels


def _finish_mip(display, raw):
    """Each volume's maximum through its own transfer function; where volumes overlap on the image, the
    brighter of their colours in each channel (a maximum of the colours, as the mode's name says)."""
    rgba = None
    for volume, maximum in zip(raw["volumes"], raw["maxima"]):
        ramp = display.ramps[volume.index]
        colours = mip_colours(maximum, control_points(ramp, volume), density_range(ramp, volume), display.mip_color,
                              volume.background)
        rgba = colours if rgba is None else np.maximum(rgba, colours)
    if rgba is None:
        rgba = np.zeros(raw["shape"] + (4,), dtype=np.float32)
    return {"Combined": over_background(rgba, display.world, display.film_transparent)}


FINISHERS = {
    'XRAY': _finish_xray,
    'SHADED': _finish_shaded,
    'MIP': _finish_mip,
}


def finish(display, raw):
    """The passes of native results `raw` (native_render.render_raw's) under DisplayInputs: {name: float32
    (height, width, channels)}."""
    pixels = FINISHERS[display.mode](display, raw)
    if "integral" in raw and "XRay" not in pixels:
        pixels["XRay"] = raw["integral"][:, :, None]
    return pixels


def viewport_pixels(display, raw):
    """The Combined pass of a viewport render."""
    return finish(display, raw)["Combined"]


def write_result(engine, depsgraph, view, pixels):
    view_layer = depsgraph.view_layer
    # Result coordinates start at the render border, when there is one.
    result = engine.begin_result(0, 0, view.width, view.height, layer=view_layer.name)
    layer = result.layers[0]
    for name, _channel_ids, _channel_type in list_render_passes(depsgraph.scene, view_layer):
        # Blender stores rows bottom to top.
        rect = np.ascontiguousarray(pixels[name][::-1], dtype=np.float32)
        layer.passes[name].rect.foreach_set(rect.ravel())
    engine.end_result(result)
