# SPDX-License-Identifier: GPL-3.0-or-later

"""One frame over several processes (`--split N`): sort-last rendering, as IceT does for ParaView.

Each of N share tasks renders the frame from its share of every streamed volume: shaded and MIP a run of the
volume's bricks in visibility order (pcvr_native's `brick_share`: bricks are cubes of voxels, ordered front to
back from the camera), X-ray a run of its batches (GridStream.with_batches). The client composites the shares'
native results in share order: X-ray integrals summed, shaded premultiplied RGBA front to back with the over
operator, MIP maxima the largest; then a worker finishes the passes and writes the image with the batch's own
code (render_task.render_job), reading no volume again: the native results carry what finishing needs. A worker lost mid-frame loses nothing: the scheduler runs its share again elsewhere.

Volumes read whole (at most Stream Above) are not split: the first share renders them (MIP: every share, a
maximum taken twice is the same). The image equals one process's to within float rounding, except that a
share does not know the opacity in front of it: where one process stops a pixel at the opacity cutoff (0.99),
later shares go on, by at most the 1% left; and the Depth pass takes, where the composited opacity passes one
half, the depth where that share's own opacity did.
"""

import dataclasses

import numpy as np

from ..render import native_render, prepared_scene
from . import split_xray


def render_share(planned, part, parts):
    """(raw native results, stats) of share `part` of `parts` of a PlannedJob, on a worker."""
    prepared = prepared_scene.prepare(planned.inputs)
    if prepared.errors:
        raise OSError("; ".join(prepared.errors))
    stats = {}
    raw = native_render.render_raw(dataclasses.replace(prepared, share=(part, parts)), planned.view, stats=stats)
    return raw, stats


def composite(shares):
    """The (raw, stats) of a frame's shares in share order, composited as one process renders the frame: raw
    results and stats (bricks and batches added up, "split": how many shares)."""
    raws = [raw for raw, _ in shares]
    raw = dict(raws[0])
    if "integral" in raw:
        raw["integral"] = split_xray.nonnegative_sum([other["integral"] for other in raws],
                                                     [share_stats for _, share_stats in shares])
    if "rgba" in raw:
        rgba = np.array(raws[0]["rgba"], dtype=np.float32)
        depth = None if raws[0]["depth"] is None else np.array(raws[0]["depth"], dtype=np.float32)
        for other in raws[1:]:
            before = rgba[..., 3].copy()
            rgba += (1.0 - rgba[..., 3:]) * other["rgba"]
            if depth is not None:
                passes_half = (before < 0.5) & (rgba[..., 3] >= 0.5)
                depth = np.where(passes_half & np.isinf(depth), other["depth"], depth)
        raw["rgba"], raw["depth"] = rgba, depth
    if "maxima" in raw:
        raw["maxima"] = [np.maximum.reduce(list(volume)) for volume in zip(*(other["maxima"] for other in raws))]
    stats = {"split": len(shares), "batches": sum(share_stats.get("batches", 0) for _, share_stats in shares)}
    return raw, stats


def render_here(planned, run_id, parts):
    """A split frame rendered share by share in this process, composited and written: its JobResult."""
    from . import render_task

    shares = [render_share(planned, part, parts) for part in range(parts)]
    return render_task.render_job(planned, run_id, rendered=composite(shares))


def run_split(client, planned_jobs, run_id, parts, done):
    """Each PlannedJob's shares on the cluster (all submitted at once), composited here frame by frame, each frame
    finished and written on a worker; `done([result])` with each JobResult as it comes."""
    from . import render_task
    from .dask_runner import _distributed

    shares = {planned.index: [client.submit(render_share, planned, part, parts, key=f"pcvr-share-{run_id}-{planned.index}-{part}",
                                            pure=False, retries=1) for part in range(parts)]
              for planned in planned_jobs}
    finishing = []
    try:
        for planned in planned_jobs:
            # Scattered: a frame's composited passes are megabytes, which Dask sends apart from the task.
            rendered = client.scatter(composite(client.gather(shares.pop(planned.index))))
            finishing.append(client.submit(render_task.render_job, planned, run_id, rendered=rendered,
                                           key=f"pcvr-finish-{run_id}-{planned.index}", pure=False, retries=1))
        for future in _distributed().as_completed(finishing):
            done([future.result()])
    finally:
        client.cancel(finishing + [future for futures in shares.values() for future in futures])
