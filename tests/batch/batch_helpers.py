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
