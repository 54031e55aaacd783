"""One frame over several processes (--split N, pcvr_addon/batch/split_frame.py): each share renders a run of the
streamed volume's bricks (shaded, MIP) or batches (X-ray), the shares are composited in visibility order, and the
image is one process's. On a real 2-process Dask cluster, a worker killed mid-frame included: test_dask_cluster.py."""

import pytest

import batch_helpers as bh
import batch_scenes


@pytest.fixture(scope="module")
def volume(tmp_path_factory):
    return batch_scenes.write_split_volume(tmp_path_factory.mktemp("split") / "blobs.vdb")


@pytest.mark.parametrize("mode", ["XRAY", "SHADED", "MIP"])
def test_a_frame_in_three_shares_is_one_process_frame(tmp_path, volume, mode):
    bh.render_split(volume, tmp_path / "one" / "f_#.exr", mode)
    document = bh.render_split(volume, tmp_path / "split" / "f_#.exr", mode, split=3)
    stats = document["jobs"][0]["stats"]
    assert document["split"] == 3 and stats["split"] == 3 and stats["batches"] >= 3  # the volume was cut
    bh.assert_close_images(bh.images(tmp_path / "split"), bh.images(tmp_path / "one"), mode)


@pytest.mark.parametrize("mode", ["SHADED", "MIP"])
def test_finishing_a_split_frame_reads_no_volume_again(tmp_path, volume, mode, monkeypatch):
    """Each share prepares (reads) the volume once; the frame is finished from the composited native results
    alone, which carry what finishing needs (MIP: each volume's density range and background)."""
    from pcvr_addon.render import prepared_scene

    open_grid, opened = prepared_scene._grid, []
    monkeypatch.setattr(prepared_scene, "_grid", lambda volume, *args: opened.append(volume.name) or
                        open_grid(volume, *args))
    bh.render_split(volume, tmp_path / "split" / "f_#.exr", mode, split=2)
    assert len(opened) == 2  # one per share
    assert bh.images(tmp_path / "split")
