"""Helpers for the native I/O tests: fresh-interpreter runs and files written by Blender's OpenVDB.

Anything that could crash the interpreter (reading corrupt files, importing bpy next to pcvr_native)
runs in a subprocess, so a crash fails one test instead of killing pytest.
"""

import functools
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import textwrap

import numpy as np

# Blender 5.0's bundled OpenVDB (12.0) Python module is reached through bpy.
BLENDER_OPENVDB_PRELUDE = """
import bpy
bpy.utils.expose_bundled_modules()
import openvdb as vdb
"""

HAVE_BPY = importlib.util.find_spec("bpy") is not None


def run_python(code, timeout=300):
    """Run `code` in a fresh interpreter (this one's executable); returns the CompletedProcess."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=timeout)


def describe(proc):
    """A failure message for a subprocess: how it ended, and its output."""
    if proc.returncode < 0:
        try:
            how = f"killed by {signal.Signals(-proc.returncode).name}"
        except ValueError:
            how = f"killed by signal {-proc.returncode}"
    else:
        how = f"exit code {proc.returncode}"
    return f"subprocess {how}\n--- stdout ---\n{proc.stdout[-4000:]}\n--- stderr ---\n{proc.stderr[-4000:]}"


def run_blender_openvdb(code, timeout=300):
    """Run `code` with Blender's bundled `openvdb` imported as `vdb` (and numpy as `np`); must succeed."""
    proc = run_python("import numpy as np\n" + BLENDER_OPENVDB_PRELUDE + textwrap.dedent(code), timeout)
    assert proc.returncode == 0, describe(proc)
    return proc


def file_grids(arrays, index_to_world):
    """{name: array} as pn.write_vdb takes them: a float Grid per (i, j, k) array, three Grids (x, y, z) per
    (i, j, k, 3) array (a vector grid, as a simulation's `color`); zeros inactive."""
    import pcvr_native as pn

    def grid(values):
        values = np.asarray(values, np.float32)
        if values.ndim == 4:
            return tuple(pn.Grid.from_dense(values[..., c], index_to_world) for c in range(3))
        return pn.Grid.from_dense(values, index_to_world)

    return {name: grid(values) for name, values in arrays.items()}


def sparse_volume(shape=(24, 20, 18), fill_fraction=0.15, seed=1):
    """A seeded float32 array: mostly zeros, a random sprinkling of positive values and one dense
    constant block (which OpenVDB stores as a tile)."""
    rng = np.random.default_rng(seed)
    values = np.where(rng.random(shape) < fill_fraction, rng.uniform(0.1, 5.0, shape), 0.0).astype(np.float32)
    values[8:16, 8:16, 8:16] = 2.5  # one whole 8^3 leaf, aligned: pruned into a constant tile
    return values


def affine_matrix(seed=2):
    """An index-to-world matrix with rotation, non-uniform scale, shear and translation."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    linear = q @ np.diag([0.5, 0.75, 1.25]) @ np.array([[1.0, 0.3, 0.0], [0.0, 1.0, -0.2], [0.0, 0.0, 1.0]])
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = [1.5, -2.0, 0.25]
    return m


@functools.lru_cache(maxsize=None)
def unprivileged_prefix():
    """(command prefix, None) that runs a command as the user 'nobody' when this process is root
    (who may read anything, so permission tests need another user), ([], None) when it is not root,
    or (None, why) when that cannot work here: no setpriv, or a checkout that 'nobody' cannot read
    (mktemp -d makes private directories)."""
    if os.geteuid() != 0:
        return [], None
    if not shutil.which("setpriv"):
        return None, "running as root without setpriv to drop privileges"
    prefix = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    probe = subprocess.run(prefix + [sys.executable, "-c", "import pcvr_native"], capture_output=True, text=True)
    if probe.returncode != 0:
        return None, "the user 'nobody' cannot read this checkout's Python environment"
    return prefix, None
