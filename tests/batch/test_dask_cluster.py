"""A real local Dask cluster of 2 worker processes: sequences and view sweeps equal to one process, a worker
killed mid-run, an X-ray of a volume split over both workers, and frames split over them (--split) in every mode,
a worker killed mid-frame included."""

import os

import numpy as np
import pytest

import batch_helpers as bh
import batch_scenes
from pcvr_addon.batch import dask_runner, split_xray

pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def client():
    client = dask_runner.connect(workers=2)
    yield client
    dask_runner.close(client)


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    directory = tmp_path_factory.mktemp("sequence")
    batch_scenes.write_sequence(directory, range(1, 7))
    return directory


def _workers(manifest_file):
    import json
    with open(manifest_file) as file:
        document = json.load(file)
    return {job["worker"] for job in document["jobs"]}, document["counts"]


def test_sequence_and_sweep_on_two_workers_equal_one_process(tmp_path, sequence, client):
    for where, on in (("here", None), ("cluster", client)):
        status, printed = bh.render(sequence / "smoke_####.vdb", tmp_path / where / "f_####_#.exr", range(1, 7),
                                    angles=[0.0, 60.0], client=on)
        assert status == 0, printed
    bh.assert_same_images(bh.images(tmp_path / "cluster"), bh.images(tmp_path / "here"))
    workers, counts = _workers(tmp_path / "cluster" / "f.manifest.json")
    assert counts == {"rendered": 12} and len(workers) == 2
    assert str(os.getpid()) not in {worker.split(":")[1] for worker in workers}


def test_a_worker_killed_mid_run_costs_only_its_tasks(tmp_path, sequence, client):
    angles = [float(a) for a in range(0, 360, 10)]
    status, _ = bh.render(sequence / "smoke_0001.vdb", tmp_path / "reference" / "v_##.exr", angles=angles)
    assert status == 0
    output = tmp_path / "cluster"
    victim = next(iter(client.run(os.getpid).values()))
    written = []

    def once_an_image_is_there():
        written.append(sum(name.endswith(".exr") for name in os.listdir(output)) if output.is_dir() else 0)
        return victim if written[-1] else None

    killer = bh.kill_worker_when(once_an_image_is_there)
    finished = [bh.render(sequence / "smoke_0001.vdb", output / "v_##.exr", angles=angles, client=client)]
    killer.join()
    assert killer.killed and written[-1] < len(angles)  # so the kill came mid-run
    status, printed = finished[0]
    assert status == 0, printed
    bh.assert_same_images(bh.images(output), bh.images(tmp_path / "reference"))
    workers, counts = _workers(output / "v.manifest.json")
    # Every image once: rendered by this run, or kept when a rerun task found it written.
    assert set(counts) <= {"rendered", "kept"} and sum(counts.values()) == len(angles)
    assert [name for name in os.listdir(output) if name.startswith(".")] == []  # no temporaries left
    # The nanny restarts the worker, which can import the renderer (it starts with this process's sys.path).
    bh.wait_for_replacement(client, victim)
    assert set(client.run(_imports_renderer).values()) == {True}


def _imports_renderer():
    from pcvr_addon.batch import render_task  # noqa: F401
    return True


def test_a_volume_split_over_two_workers_sums_to_the_streamed_render(tmp_path, client):
    import pcvr_native as pn
    import pcvr_native.cameras

    values = np.zeros((300, 260, 20), np.float32)
    values[5:290, 10:250, 2:18] = np.random.default_rng(1).random((285, 240, 16), dtype=np.float32) + 0.1
    path = str(tmp_path / "wide.vdb")
    pn.Grid.from_dense(values, np.diag([0.1, 0.1, 0.1, 1.0])).write_vdb(path)
    view = np.eye(4)
    view[:3, 3] = [-15.0, -13.0, -10.0]
    camera = pn.Camera(view, pn.cameras.ortho(-16, 16, -14, 14, 0.1, 20), 160, 140)
    memory_limit = 2 << 20  # batches of 1 MiB of a 7 MiB volume
    stream = pn.stream_vdb(path)
    batches = stream.batch_count(split_xray.batch_bytes(stream, memory_limit))
    assert batches >= 4

    single_stats = {}
    single = pn.render_xray(stream, camera, memory_limit=memory_limit, level=0, stats=single_stats)
    assert single_stats["batches"] == batches
    split = split_xray.render_xray_split(client, path, camera, parts=2, memory_limit=memory_limit)
    assert np.array_equal(split, single)
    # A share alone is not the whole.
    share = split_xray.render_batches(path, split_xray._camera_values(camera), [0, 2], 1 << 20,
                                      memory_limit=memory_limit, level=0)
    assert not np.allclose(split_xray.nonnegative_sum(*zip(*share.values())), single, atol=1e-3)


@pytest.mark.parametrize("where", ["--scheduler", "--workers"])
def test_command_line_joins_a_cluster_or_starts_one(tmp_path, sequence, client, where):
    from pcvr_addon.cli import main as cli

    argv = ["render", str(sequence / "smoke_####.vdb"), "--frames", "1-2", "-o", str(tmp_path / "f_####.exr")]
    argv += [where, client.scheduler.address if where == "--scheduler" else "1"]
    assert cli.main(argv) == 0
    workers, counts = _workers(tmp_path / "f.manifest.json")
    assert counts == {"rendered": 2}
    if where == "--scheduler":
        assert workers <= {f"{info['host']}:{info['pid']}" for info in _worker_info(client)}
    assert len(client.run(os.getpid)) == 2  # joining a cluster leaves it running


def _worker_info(client):
    import socket
    pids = client.run(os.getpid)
    return [{"host": socket.gethostname(), "pid": pid} for pid in pids.values()]


@pytest.fixture(scope="module")
def split_volume(tmp_path_factory):
    return batch_scenes.write_split_volume(tmp_path_factory.mktemp("split") / "blobs.vdb")


def test_two_workers_split_every_mode_as_one_process(tmp_path, split_volume, client):
    from pcvr_addon.cli import main as cli

    for mode in ("XRAY", "SHADED", "MIP"):
        bh.render_split(split_volume, tmp_path / mode / "one" / "f_#.exr", mode)
        argv = ["render", str(split_volume), "-o", str(tmp_path / mode / "split" / "f_#.exr"), "--angles", "20:21:1",
                "--mode", mode.lower(), "--stream-above", "1", "--opacity-cutoff", "1", "--magnification", "0.5",
                "--scheduler", client.scheduler.address, "--split", "2"]
        assert cli.main(argv) == 0
        bh.assert_close_images(bh.images(tmp_path / mode / "split"), bh.images(tmp_path / mode / "one"), mode)


def test_a_worker_killed_mid_frame_loses_nothing(tmp_path, split_volume, client):
    """The worker rendering a share is killed outright while it renders: the scheduler runs the share again on
    the other worker (and the nanny starts a new one), and every frame is whole."""
    angles = [0.0, 40.0]
    bh.render_split(split_volume, tmp_path / "one" / "v_#.exr", "SHADED", angles=angles)

    def a_worker_rendering_a_share():
        for address, keys in client.processing().items():
            if any(str(key).startswith("pcvr-share-") for key in keys):
                return client.run(os.getpid, workers=[address]).get(address)
        return None

    killer = bh.kill_worker_when(a_worker_rendering_a_share)
    document = bh.render_split(split_volume, tmp_path / "split" / "v_#.exr", "SHADED", split=2, client=client,
                               angles=angles)
    killer.join()
    killed = killer.killed
    assert killed, "no share was seen running"
    assert document["counts"] == {"rendered": len(angles)}
    bh.assert_close_images(bh.images(tmp_path / "split"), bh.images(tmp_path / "one"), "SHADED")
    bh.wait_for_replacement(client, killed[0])
