"""Bad files and failed writes: every failure is a Python exception that names the file; nothing crashes.

Damaged files are read in a subprocess, one damage after another, each announced before it is read:
if the reader crashes, the test fails and names the damage that did it, and pytest survives.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
import pytest

import pcvr_native as pn
from _io_helpers import HAVE_BPY, describe, run_blender_openvdb, run_python, sparse_volume, unprivileged_prefix

# Reads every damaged copy of a file with read_vdb and list_grids (and, when reading succeeds, walks
# the voxel blocks), and streams it into an X-ray (which decodes every leaf), printing one JSON line per
# case. argv: source file, cases JSON file, work dir.
DAMAGE_RUNNER = r"""
import json, os, sys
import numpy as np
import pcvr_native as pn

def stream_and_render(path):
    projection = np.diag([0.05, 0.05, -0.01, 1.0])
    pn.render_xray(pn.stream_vdb(path, batch_bytes=1), pn.Camera(np.eye(4), projection, 16, 16))

source, cases_file, work = sys.argv[1:4]
data = open(source, 'rb').read()
for case in json.load(open(cases_file)):
    damaged = bytearray(data[:case['truncate']] if 'truncate' in case else data)
    for offset, value in case.get('bytes', []):
        damaged[offset] = value
    path = os.path.join(work, 'damaged.vdb')
    with open(path, 'wb') as f:
        f.write(damaged)
    print(json.dumps({'start': case}), flush=True)
    results = []
    for call in (pn.read_vdb, pn.list_grids, stream_and_render):
        try:
            value = call(path)
            if isinstance(value, pn.Grid):
                value.block_count
                try:
                    value.to_dense()
                except ValueError:
                    pass  # a corrupt origin can make the bounding box too large for a dense copy
            results.append({'ok': True})
        except Exception as e:
            results.append({'type': type(e).__name__, 'message': str(e)})
    print(json.dumps({'case': case, 'results': results}), flush=True)
print('done', flush=True)
"""


def run_damage_cases(source, cases, tmp_path):
    """Read each damaged copy of `source` in one subprocess; returns [(case, [read_vdb, list_grids, stream
    results])]."""
    cases_file = tmp_path / "cases.json"
    cases_file.write_text(json.dumps(cases))
    work = tmp_path / "work"
    work.mkdir(exist_ok=True)
    proc = run_python(f"import sys; sys.argv = ['runner', {str(source)!r}, {str(cases_file)!r}, {str(work)!r}]\n"
                      + DAMAGE_RUNNER, timeout=600)
    lines = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode != 0 or not proc.stdout.rstrip().endswith("done"):
        started = [line["start"] for line in lines if "start" in line]
        crashed_on = started[-1] if started else None
        pytest.fail(f"reader died on damage {crashed_on} of {source.name}\n{describe(proc)}")
    return [(line["case"], line["results"]) for line in lines if "case" in line]


def write_source(tmp_path, compression):
    """A grid with scattered leaves and one constant tile, written by us."""
    path = tmp_path / f"source_{compression}.vdb"
    pn.Grid.from_dense(sparse_volume(shape=(40, 36, 30), seed=7), np.eye(4)).write_vdb(path, compression=compression)
    return path


def blender_source(tmp_path):
    """Several grids of several types, written by Blender's OpenVDB 12 (blosc)."""
    path = tmp_path / "source_blender.vdb"
    run_blender_openvdb(f"""
        rng = np.random.default_rng(5)
        grids = []
        for name, cls, dtype in [('temperature', vdb.FloatGrid, np.float32), ('density', vdb.FloatGrid, np.float32),
                                 ('heat', vdb.DoubleGrid, np.float64), ('flags', vdb.Int32Grid, np.int32)]:
            g = cls(); g.name = name
            g.copyFromArray((rng.random((30, 30, 30)) * 10 * (rng.random((30, 30, 30)) < 0.3)).astype(dtype))
            grids.append(g)
        vdb.write({str(path)!r}, grids)
    """)
    return path


SOURCES = ["blosc", "zip", "none", pytest.param("blender", marks=pytest.mark.skipif(not HAVE_BPY, reason="no bpy"))]


def make_source(tmp_path, kind):
    return blender_source(tmp_path) if kind == "blender" else write_source(tmp_path, kind)


# ------------------------------------------------------------------------------------------------

def test_missing_file_raises_file_not_found(tmp_path):
    path = str(tmp_path / "missing.vdb")
    for call in (pn.read_vdb, pn.list_grids):
        with pytest.raises(FileNotFoundError, match=re.escape(path)):
            call(path)


def test_directory_is_not_a_vdb(tmp_path):
    for call in (pn.read_vdb, pn.list_grids):
        with pytest.raises(pn.VDBReadError, match=re.escape(str(tmp_path)) + ".*is a directory"):
            call(tmp_path)


def test_file_without_read_permission():
    """As root (who may read anything) the read runs as 'nobody' in a directory it may enter."""
    prefix, why_not = unprivileged_prefix()
    if prefix is None:
        pytest.skip(why_not)
    directory = tempfile.mkdtemp(prefix="pcvr_unreadable_")
    try:
        os.chmod(directory, 0o755)
        path = os.path.join(directory, "secret.vdb")
        pn.Grid.from_dense(sparse_volume(shape=(8, 8, 8)), np.eye(4)).write_vdb(path)
        os.chmod(path, 0)
        code = f"""
            import pcvr_native as pn
            for call in (pn.read_vdb, pn.list_grids):
                try:
                    call({path!r})
                except pn.VDBReadError as e:
                    print(type(e).__name__, e)
        """
        proc = subprocess.run(prefix + [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                              timeout=120)
        assert proc.returncode == 0, describe(proc)
        lines = proc.stdout.splitlines()
        assert len(lines) == 2, proc.stdout
        for line in lines:
            assert line.startswith("VDBReadError cannot open") and "secret.vdb" in line and "Permission denied" in line, line
    finally:
        shutil.rmtree(directory)


@pytest.mark.parametrize("kind", SOURCES)
def test_truncated_files_raise_vdb_read_error(tmp_path, kind):
    source = make_source(tmp_path, kind)
    size = source.stat().st_size
    offsets = sorted(set(np.linspace(0, size - 1, 20).astype(int).tolist() + [8, 16, 100, size - 8, size - 1]))
    for case, results in run_damage_cases(source, [{"truncate": n} for n in offsets], tmp_path):
        for result in results:
            assert result.get("type") == "VDBReadError", (case, result)
            assert "damaged.vdb" in result["message"], (case, result)


@pytest.mark.parametrize("kind", SOURCES)
def test_corrupted_files_never_crash(tmp_path, kind):
    source = make_source(tmp_path, kind)
    size = source.stat().st_size
    rng = np.random.default_rng(11)
    cases = []
    for n in range(40):
        # A quarter of the cases hit the first 600 bytes: header, metadata, descriptors, root node.
        limit = min(size, 600) if n % 4 == 0 else size
        flips = [[int(rng.integers(0, limit)), int(rng.integers(0, 256))] for _ in range(int(rng.integers(1, 5)))]
        cases.append({"bytes": flips})
    outcomes = {"ok": 0, "VDBReadError": 0, "GridError": 0}
    for case, results in run_damage_cases(source, cases, tmp_path):
        for result in results:
            kind_ = "ok" if result.get("ok") else result["type"]
            assert kind_ in outcomes, (case, result)
            if kind_ != "ok":
                assert "damaged.vdb" in result["message"], (case, result)
            outcomes[kind_] += 1
    assert sum(outcomes.values()) == 3 * len(cases)


# ------------------------------------------------------------------------------------------------
# Writing

def small_grid():
    return pn.Grid.from_dense(sparse_volume(shape=(12, 12, 12)), np.eye(4))


@pytest.mark.parametrize("target", ["missing_dir/out.vdb", "a_file/out.vdb"])
def test_write_to_unwritable_location_raises_and_leaves_nothing(tmp_path, target):
    (tmp_path / "a_file").write_text("I am a file")
    path = tmp_path / target
    with pytest.raises(OSError, match=re.escape(str(path))):
        small_grid().write_vdb(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root may write anywhere")
def test_write_to_read_only_directory(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(OSError, match="out.vdb"):
            small_grid().write_vdb(ro / "out.vdb")
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o755)


def test_write_onto_a_directory_fails_without_leftovers(tmp_path):
    target = tmp_path / "dir.vdb"
    target.mkdir()
    (target / "keep").write_text("x")
    with pytest.raises(OSError, match="dir.vdb"):
        small_grid().write_vdb(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.vdb"]
    assert [p.name for p in target.iterdir()] == ["keep"]


def test_failed_write_keeps_the_old_file(tmp_path):
    """A write that fails halfway (here: the file size limit) leaves the previous file intact."""
    target = tmp_path / "volume.vdb"
    old = b"previous contents " * 10
    target.write_bytes(old)
    proc = run_python(f"""
        import resource, signal
        import numpy as np, pcvr_native as pn
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)   # over-limit writes fail with EFBIG instead
        values = np.random.default_rng(0).random((64, 64, 64), dtype=np.float32) + 1
        grid = pn.Grid.from_dense(values, np.eye(4))
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))
        try:
            grid.write_vdb({str(target)!r}, compression='none')
            print('WROTE')
        except OSError as e:
            print('OSError:', e)
    """)
    assert proc.returncode == 0, describe(proc)
    assert "OSError:" in proc.stdout and str(target) in proc.stdout, describe(proc)
    assert target.read_bytes() == old
    assert sorted(p.name for p in tmp_path.iterdir()) == ["volume.vdb"]
