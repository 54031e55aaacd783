# SPDX-License-Identifier: GPL-3.0-or-later

"""An X-ray of a volume bigger than one worker: its batches of 128^3 regions rendered on several, summed.

pcvr_native's streamed X-ray (render_xray of a GridStream, native/src/streamed_xray.cpp) reads a file a batch
of regions at a time, renders each batch and adds the images in batch order. Here each worker renders a share
of the batches (GridStream.with_batches: the same stream, the same level and settings, only those batches),
returns one image per batch, and the images are added here in the same order, as float32: the sum is the
single-process streamed render bit for bit, and no worker holds more than a batch of values (half of
`memory_limit`) and its buffers.

Shaded and MIP images are not sums: a frame of those modes is split as bricks composited front to back
(split_frame.py, the command line's --split).
"""

import numpy as np

from ..render.prepared_scene import xray_batch_bytes as batch_bytes  # noqa: F401 (render_xray's batch size)


def _camera_values(camera):
    """A pcvr_native.Camera as plain values, which pickle (the Camera itself does not)."""
    return (np.asarray(camera.world_to_camera), np.asarray(camera.projection), camera.width, camera.height)


def render_batches(path, camera_values, batches, size, grid=None, **xray_options):
    """{batch: (image, stats)} of the batches `batches` (of `size` bytes each) of grid `grid` of `path`, each
    rendered alone as render_xray renders it within the whole stream (uncorrected: see nonnegative_sum)."""
    import pcvr_native

    stream = pcvr_native.stream_vdb(path, grid)
    camera = pcvr_native.Camera(*camera_values)
    rendered = {}
    for batch in batches:
        stats = {}
        image = pcvr_native.render_xray(stream.with_batches([batch], size), camera, stats=stats, **xray_options)
        rendered[batch] = image, stats
    return rendered


def render_xray_split(client, path, camera, grid=None, parts=None, memory_limit=None, level=0, **xray_options):
    """The X-ray of grid `grid` of the .vdb `path` seen by `camera` (pcvr_native.Camera), its batches rendered
    on the workers of the Dask `client` in `parts` shares (default: one per worker), summed here: equal to
    pcvr_native.render_xray(pcvr_native.stream_vdb(path, grid), camera, memory_limit=memory_limit, level=level,
    **xray_options), bit for bit. `level` must be a number (the whole stream's "auto" level is chosen by the
    native render). Returns the float32 (height, width) integral."""
    import pcvr_native

    if not isinstance(level, int):
        raise ValueError("render_xray_split: level must be a level of detail (0, 1, ...), not 'auto'")
    options = dict(xray_options, memory_limit=memory_limit, level=level)
    stream = pcvr_native.stream_vdb(path, grid)
    size = batch_bytes(stream, memory_limit)
    count = stream.batch_count(size)
    if count == 1 or (level > 0 and stream.value_bytes >> (3 * level) <= size):
        # One batch, or a coarse level that fits where a batch would: the stream renders it whole.
        return client.submit(_render_whole, path, _camera_values(camera), grid, options, pure=False).result()
    parts = parts or len(client.scheduler_info()["workers"])
    shares = [list(range(count))[part::parts] for part in range(min(parts, count))]
    futures = [client.submit(render_batches, path, _camera_values(camera), share, size, grid, pure=False,
                             **options) for share in shares]
    images = {}
    for future in futures:
        images.update(future.result())
    return nonnegative_sum(*zip(*(images[batch] for batch in range(count))))


def _render_whole(path, camera_values, grid, options):
    import pcvr_native

    return pcvr_native.render_xray(pcvr_native.stream_vdb(path, grid), pcvr_native.Camera(*camera_values), **options)


def summed_in_order(images):
    """Images added in the order given, as float32: as the streamed render adds its batches' images."""
    total = np.array(images[0], dtype=np.float32, copy=True)
    for image in images[1:]:
        total += image
    return total


def nonnegative_sum(images, stats):
    """The parts' images summed in order and, where every part was of a field >= 0 (their stats), the sum's
    ringing below zero cleared as one streamed render clears its own: parts render uncorrected so that they add
    up (the correction is not linear)."""
    import pcvr_native

    total = summed_in_order(images)
    if all(part.get("nonnegative", False) for part in stats):
        pcvr_native.clear_negative_pixels(total, max(part["ringing_reach"] for part in stats))
    return total
