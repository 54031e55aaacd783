"""Running batches from the tests and comparing their images."""

import io
import os

import numpy as np

from pcvr_addon.cli import main as cli
from pcvr_addon.io import image_io
from pcvr_addon.batch import jobs, run


def defaults():
    """The render options of `python -m pcvr_addon render` when none is given."""
    return run._render_defaults(cli.make_parser())


def render(input_path, output, frames=None, angles=None, options=None, client=None, skip_existing=False,
           run_id=None, split=1):
    """Render a batch; (exit status, what it printed)."""
    batch = jobs.expand(str(input_path), str(output), frames, angles, options)
    printed = io.StringIO()
    status = run.render_batch(batch, manifest_file(output), defaults(), client, skip_existing, stream=printed,
                              run_id=run_id, split=split)
    return status, printed.getvalue()


def manifest_file(output):
    from pcvr_addon.batch import manifest
    return manifest.manifest_path(str(output))


def images(directory):
    """{file name: pixels} of the images in `directory`."""
    return {name: image_io.read_passes(os.path.join(directory, name))[""]
            for name in sorted(os.listdir(directory)) if os.path.splitext(name)[1] in image_io.FORMATS}


def assert_same_images(first, second):
    assert first.keys() == second.keys()
    for name in first:
        assert np.array_equal(first[name], second[name]), name


# --split's test volume (batch_scenes.write_split_volume): Stream Above 1 MiB streams its 3.1 MiB, in bricks of at
# most 1 MiB of values (X-ray: batches of its four 128^3 regions); opacity cutoff 1: only rounding parts the shares
# from one process (with 0.99 a share goes on where one process stops, by at most the 1% left). Half a pixel a
# voxel: the tests' time is the bricks'.
SPLIT_OPTIONS = {"stream_above": 1, "opacity_cutoff": 1.0, "magnification": 0.5}


def render_split(volume, output, mode, split=1, client=None, angles=(20.0,)):
    """A batch of `volume` in `mode` at SPLIT_OPTIONS, each frame in `split` shares; its manifest."""
    import json

    status, printed = render(volume, output, angles=list(angles), options={"mode": mode, **SPLIT_OPTIONS}, client=client,
                             split=split)
    assert status == 0, printed
    with open(manifest_file(output)) as file:
        return json.load(file)


def assert_close_images(first, second, mode):
    """Split frames against one process's: X-ray shares summed in another order than the batches (rounding);
    shaded RGBA composited over (rounding, measured 2.4e-7), its Depth pass apart (split_frame.py); MIP the same
    maxima."""
    assert first.keys() == second.keys()
    for name in first:
        a, b = first[name][..., :4], second[name][..., :4]
        assert a[..., 3].max() > 0.5, name  # the volume shows
        np.testing.assert_allclose(a, b, rtol=0, atol=0 if mode == "MIP" else 1e-5, err_msg=name)


def kill_worker_when(victim, seconds=120):
    """A started thread that kills, outright (SIGKILL, as a machine lost), the worker process whose pid `victim()`
    returns, polling it until it returns one; the thread's `killed` lists the pid. (A thread of its own: bpy, which
    the batch uses while planning, must stay on the main thread.)"""
    import signal
    import threading
    import time

    def watch():
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            pid = victim()
            if pid:
                os.kill(pid, signal.SIGKILL)
                thread.killed.append(pid)
                return
            time.sleep(0.005)

    thread = threading.Thread(target=watch)
    thread.killed = []
    thread.start()
    return thread


def wait_for_replacement(client, victim, workers=2, seconds=180):
    """Wait until the cluster has `workers` workers again, none of them the killed process `victim` (a new worker
    imports bpy: over 60 s once under the whole suite on a loaded machine)."""
    import time

    deadline = time.monotonic() + seconds
    while len(client.run(os.getpid)) < workers:
        assert time.monotonic() < deadline, "the killed worker was not replaced"
        time.sleep(0.2)
    assert victim not in client.run(os.getpid).values()
