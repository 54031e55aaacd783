"""One frame over several processes (--split N, pcvr_addon/batch/split_frame.py): each share renders a run of the
streamed volume's bricks (shaded, MIP) or batches (X-ray), the client composites them in visibility order, and the
image is one process's; on a real 2-process Dask cluster too, where a worker killed mid-frame loses nothing."""

import json
import os
import signal
import threading
import time

import numpy as np
import pytest

import batch_helpers as bh
import pcvr_native as pn

# Stream Above 2 MiB: the 6.2 MiB volume streams, in bricks of at most 2 MiB of values (X-ray: batches of its
# four 128^3 regions); opacity cutoff 1: only rounding parts the shares from one process (with 0.99 a share goes
# on where one process stops, by at most the 1% left).
OPTIONS = {"stream_above": 2, "opacity_cutoff": 1.0}


@pytest.fixture(scope="module")
def volume(tmp_path_factory):
    """Smooth blobs over 192 x 192 x 48 voxels: four 128^3 regions, every voxel active."""
    i, j, k = np.meshgrid(np.arange(192), np.arange(192), np.arange(48), indexing="ij", sparse=True)
    values = 0.05 + sum(np.exp(-((i - ci) ** 2 + (j - cj) ** 2 + (k - ck) ** 2) / (2 * s ** 2))
                        for ci, cj, ck, s in [(60, 70, 20, 25), (130, 120, 28, 30), (100, 40, 24, 12)])
    path = tmp_path_factory.mktemp("split") / "blobs.vdb"
    pn.Grid.from_dense(values.astype(np.float32), np.diag([0.1, 0.1, 0.1, 1.0])).write_vdb(str(path))
    return path


def render(volume, output, mode, split=1, client=None, angles=(20.0,)):
    status, printed = bh.render(volume, output, angles=list(angles), options={"mode": mode, **OPTIONS}, client=client,
                                split=split)
    assert status == 0, printed
    with open(bh.manifest_file(output)) as file:
        return json.load(file)


def assert_close_images(first, second, mode):
    """X-ray: shares summed in another order than the batches (rounding); shaded: RGBA composited over, rounding
    (measured 2.4e-7), the Depth pass apart (split_frame.py); MIP: the same maxima."""
    assert first.keys() == second.keys()
    for name in first:
        a, b = first[name][..., :4], second[name][..., :4]
        assert a[..., 3].max() > 0.5, name  # the volume shows
        np.testing.assert_allclose(a, b, rtol=0, atol=0 if mode == "MIP" else 1e-5, err_msg=name)


@pytest.mark.parametrize("mode", ["XRAY", "SHADED", "MIP"])
def test_a_frame_in_three_shares_is_one_process_frame(tmp_path, volume, mode):
    render(volume, tmp_path / "one" / "f_#.exr", mode)
    document = render(volume, tmp_path / "split" / "f_#.exr", mode, split=3)
    stats = document["jobs"][0]["stats"]
    assert document["split"] == 3 and stats["split"] == 3 and stats["batches"] >= 3  # the volume was cut
    assert_close_images(bh.images(tmp_path / "split"), bh.images(tmp_path / "one"), mode)


@pytest.fixture(scope="module")
def client():
    pytest.importorskip("distributed")
    from pcvr_addon.batch import dask_runner

    client = dask_runner.connect(workers=2)
    yield client
    dask_runner.close(client)


def test_two_workers_split_every_mode_as_one_process(tmp_path, volume, client):
    from pcvr_addon.cli import main as cli

    for mode in ("XRAY", "SHADED", "MIP"):
        render(volume, tmp_path / mode / "one" / "f_#.exr", mode)
        argv = ["render", str(volume), "-o", str(tmp_path / mode / "split" / "f_#.exr"), "--angles", "20:21:1",
                "--mode", mode.lower(), "--stream-above", "2", "--opacity-cutoff", "1", "--scheduler",
                client.scheduler.address, "--split", "2"]
        assert cli.main(argv) == 0
        assert_close_images(bh.images(tmp_path / mode / "split"), bh.images(tmp_path / mode / "one"), mode)


def test_a_worker_killed_mid_frame_loses_nothing(tmp_path, volume, client):
    """The worker rendering a share is killed outright while it renders: the scheduler runs the share again on
    the other worker (and the nanny starts a new one), and every frame is whole."""
    angles = [0.0, 40.0, 80.0]
    render(volume, tmp_path / "one" / "v_#.exr", "SHADED", angles=angles)
    killed = []

    def kill_a_worker_rendering_a_share():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            for address, keys in client.processing().items():
                if any(str(key).startswith("pcvr-share-") for key in keys):
                    pid = client.run(os.getpid, workers=[address]).get(address)
                    if pid:
                        os.kill(pid, signal.SIGKILL)
                        killed.append(pid)
                        return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_a_worker_rendering_a_share)
    killer.start()
    document = render(volume, tmp_path / "split" / "v_#.exr", "SHADED", split=2, client=client, angles=angles)
    killer.join()
    assert killed, "no share was seen running"
    assert document["counts"] == {"rendered": len(angles)}
    assert_close_images(bh.images(tmp_path / "split"), bh.images(tmp_path / "one"), "SHADED")
    deadline = time.monotonic() + 60
    while len(client.run(os.getpid)) < 2:  # the nanny replaced the killed worker
        assert time.monotonic() < deadline, "the killed worker was not replaced"
        time.sleep(0.2)
    assert killed[0] not in client.run(os.getpid).values()
