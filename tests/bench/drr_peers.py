"""The DRR bench's peers on one cone-beam geometry: plastimatch `drr` (Siddon "exact" and "uniform" steps) as a
child process, RTK's Joseph forward projector (itk-rtk) in this process.

Each peer gets the volume already in attenuation (mu per millimetre, the Hounsfield map applied once, as PCVR's
grid) and no conversion of its own, so that all integrate the same field:

| peer         | how the geometry is given                                     | units of its output       | threads            |
|--------------|---------------------------------------------------------------|---------------------------|--------------------|
| plastimatch  | `--sad --sid -n (isocentre to source) --vup -o -r -z`,         | mu x cm (it divides the   | OMP_NUM_THREADS     |
|              | `-P none`, `-t raw` (float32, row 0 the top); a circular       | mm integral by 10): x 10  |                    |
|              | sweep by `-y -a -N` (source at (cos a, -sin a, 0): a = 90 -   |                           |                    |
|              | gantry; -y in radians, -N in degrees)                         |                           |                    |
| RTK Joseph   | ThreeDCircularProjectionGeometry.AddProjection(source,         | mu x mm                   | ITK's global default |
|              | detector centre, row vector = image right, column vector =    |                           | number of threads   |
|              | image down), the world moved so that the isocentre is RTK's    |                           |                    |
|              | origin                                                        |                           |                    |

Times are the peers' own: plastimatch's printed "Total time" less its "I/O time" (the render, without loading the
volume or writing images), RTK's filter update (the projection stack's allocation included). CPU seconds (user and
system, all threads) go with them, less robust to a busy machine's waits: plastimatch's are its process's less those
of the same process drawing one pixel (loading the volume), the least of LOAD_RUNS.
"""

from __future__ import annotations

import math
import os
import re
import resource
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

PLASTIMATCH_MM_PER_UNIT = 10.0   # plastimatch reports mu x cm ("Translate from mm pixels to cm*gm")
LOAD_RUNS = 3


def cpu_seconds(who=resource.RUSAGE_SELF) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


class PeerUnavailable(RuntimeError):
    """A peer cannot run here (the message says why and how to install it)."""


def write_metaimage(path: Path, values: np.ndarray, index_to_world) -> None:
    """A float32 MetaImage (.mha) of values[i, j, k] placed by an axis-aligned `index_to_world`."""
    xf = np.asarray(index_to_world, dtype=np.float64)
    spacing = np.diag(xf)[:3]
    if np.abs(xf[:3, :3] - np.diag(spacing)).max() > 1e-9 * spacing.max() or np.any(spacing <= 0):
        raise ValueError(f"{path}: plastimatch reads axis-aligned volumes; index_to_world {xf.tolist()} is not")
    header = (f"ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
              f"TransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = {' '.join(map(repr, xf[:3, 3].tolist()))}\n"
              f"ElementSpacing = {' '.join(map(repr, spacing.tolist()))}\n"
              f"DimSize = {' '.join(map(str, values.shape))}\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n")
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.ascontiguousarray(values.transpose(2, 1, 0), dtype="<f4").tobytes())


class Plastimatch:
    """plastimatch `drr` on a volume written once as .mha; `algorithm` "exact" (Siddon) or "uniform"."""

    def __init__(self, values, index_to_world, threads: int, workdir: Path):
        self.executable = shutil.which("plastimatch")
        if not self.executable:
            raise PeerUnavailable("plastimatch is not installed (`apt-get install plastimatch`)")
        self.threads = threads
        self.workdir = Path(tempfile.mkdtemp(prefix="plastimatch-", dir=workdir))
        self.volume = self.workdir / "mu.mha"
        write_metaimage(self.volume, values, index_to_world)
        self.load_cpu = 0.0
        self.load_cpu = min(self._run("exact", None, None, [], pixel=True)[2] for _ in range(LOAD_RUNS))

    def version(self) -> str:
        out = subprocess.run([self.executable, "--version"], capture_output=True, text=True)
        return (out.stdout.strip() or out.stderr.strip()).splitlines()[-1]

    def _run(self, algorithm: str, geom, isocentre, orientation: list[str], pixel=False):
        """(images, render seconds, CPU seconds less loading's, wall seconds of the whole process); `pixel`: one
        pixel of the default view, to measure loading."""
        if pixel:
            cols = rows = 1
            du = dv = 1.0
            placement = []
        else:
            cols, rows = geom.detector
            du, dv = geom.pixel_spacing
            if cols != rows or du != dv:
                raise ValueError("the bench's plastimatch runs take square detectors with square pixels")
            sid = float(np.linalg.norm(geom.detector_centre - geom.source))
            sad = float(np.linalg.norm(np.asarray(isocentre) - geom.source))
            placement = ["--sad", repr(sad), "--sid", repr(sid),
                         "-o", " ".join(map(repr, np.asarray(isocentre, dtype=float).tolist()))]
        out = self.workdir / "drr_"
        for old in self.workdir.glob("drr_*"):
            old.unlink()
        command = [self.executable, "drr", "-A", "cpu", "-i", algorithm, "-P", "none", "-t", "raw", *placement,
                   "-r", f"{rows} {cols}", "-z", f"{rows * dv} {cols * du}", *orientation,
                   "-O", str(out), "-I", str(self.volume)]
        env = dict(os.environ, OMP_NUM_THREADS=str(self.threads))
        cpu0, t0 = cpu_seconds(resource.RUSAGE_CHILDREN), time.perf_counter()
        proc = subprocess.run(command, capture_output=True, text=True, env=env)
        wall, cpu = time.perf_counter() - t0, cpu_seconds(resource.RUSAGE_CHILDREN) - cpu0 - self.load_cpu
        if proc.returncode != 0:
            raise RuntimeError(f"plastimatch drr failed ({proc.returncode}): {proc.stderr.strip()[-400:]}")
        total = re.findall(r"Total time:\s*([0-9.eE+-]+)", proc.stdout)
        io = sum(float(s) for s in re.findall(r"I/O time:\s*([0-9.eE+-]+)", proc.stdout))
        if not total:
            raise RuntimeError(f"plastimatch drr printed no total time: {proc.stdout.strip()[-400:]}")
        images = [np.fromfile(path, dtype="<f4").reshape(rows, cols) * PLASTIMATCH_MM_PER_UNIT
                  for path in sorted(self.workdir.glob("drr_*.raw"))]
        return images, float(total[-1]) - io, cpu, wall

    def render(self, algorithm: str, geom, isocentre) -> tuple[np.ndarray, float, float]:
        """One DRR of the view `geom` (a cone_beam_reference.ConeBeamGeometry): (image, seconds, CPU seconds)."""
        towards_source = geom.source - np.asarray(isocentre, dtype=np.float64)
        towards_source /= np.linalg.norm(towards_source)
        images, seconds, cpu, _ = self._run(algorithm, geom, isocentre,
                                            ["-n", " ".join(map(repr, towards_source.tolist())),
                                             "--vup", " ".join(map(repr, geom.up.tolist()))])
        return images[0], seconds, cpu

    def sweep(self, algorithm: str, geom, isocentre, gantries) -> tuple[list[np.ndarray], float, float]:
        """A circular orbit (tilt 0) in one process: (images, render seconds, wall seconds with loading)."""
        step = float(np.diff(gantries).mean()) if len(gantries) > 1 else 0.0
        if len(gantries) > 1 and np.ptp(np.diff(gantries)) > 1e-9:
            raise ValueError("a plastimatch sweep takes equally spaced gantry angles")
        # plastimatch's source sits at (cos a, -sin a, 0): a = 90 - gantry, so its angles grow as ours fall.
        # Its -N is in degrees, but 1.9.4 takes -y's start angle in radians (its help says degrees).
        start = math.radians((90.0 - gantries[-1]) % 360.0)
        images, seconds, _, wall = self._run(algorithm, geom, isocentre, ["-y", repr(start), "-a", str(len(gantries)),
                                                                          "-N", repr(step)])
        return images[::-1], seconds, wall


class RtkJoseph:
    """RTK's Joseph forward projector; the volume is made an ITK image once and kept."""

    def __init__(self, values, index_to_world, threads: int, isocentre):
        try:
            import itk
            from itk import RTK as rtk
        except ImportError as e:
            raise PeerUnavailable(f"itk-rtk is not importable ({e}; `pip install itk-rtk`)") from e
        self.itk, self.rtk = itk, rtk
        itk.MultiThreaderBase.SetGlobalDefaultNumberOfThreads(threads)
        self.threads = threads
        self.isocentre = np.asarray(isocentre, dtype=np.float64)
        xf = np.asarray(index_to_world, dtype=np.float64)
        self.volume = itk.image_from_array(np.ascontiguousarray(values.transpose(2, 1, 0), dtype=np.float32))
        self.volume.SetSpacing(np.linalg.norm(xf[:3, :3], axis=0).tolist())
        direction = xf[:3, :3] / np.linalg.norm(xf[:3, :3], axis=0)
        self.volume.SetDirection(itk.matrix_from_array(np.ascontiguousarray(direction)))
        self.volume.SetOrigin((xf[:3, 3] - self.isocentre).tolist())   # RTK's origin is the isocentre

    def version(self) -> str:
        from importlib.metadata import version
        return f"itk-rtk {version('itk-rtk')}, itk {self.itk.Version.GetITKVersion()}"

    def _geometry(self, views):
        itk = self.itk
        geometry = self.rtk.ThreeDCircularProjectionGeometry.New()
        for geom in views:
            point = lambda p: itk.Point[itk.D, 3]([float(x) for x in p - self.isocentre])  # noqa: E731
            vector = lambda v: itk.Vector[itk.D, 3]([float(x) for x in v])  # noqa: E731
            if not geometry.AddProjection(point(geom.source), point(geom.detector_centre), vector(geom.right),
                                          vector(-geom.up)):
                raise RuntimeError("RTK refused the projection geometry")
        return geometry

    def _project(self, views) -> tuple[np.ndarray, float, float]:
        itk, rtk = self.itk, self.rtk
        cols, rows = views[0].detector
        du, dv = views[0].pixel_spacing
        image_type = itk.Image[itk.F, 3]
        cpu0, t0 = cpu_seconds(), time.perf_counter()
        stack = rtk.ConstantImageSource[image_type].New()
        stack.SetOrigin([-(cols - 1) / 2.0 * du, -(rows - 1) / 2.0 * dv, 0.0])
        stack.SetSpacing([du, dv, 1.0])
        stack.SetSize([cols, rows, len(views)])
        stack.SetConstant(0.0)
        projector = rtk.JosephForwardProjectionImageFilter[image_type, image_type].New()
        projector.SetInput(0, stack.GetOutput())
        projector.SetInput(1, self.volume)
        projector.SetGeometry(self._geometry(views))
        projector.Update()
        seconds, cpu = time.perf_counter() - t0, cpu_seconds() - cpu0
        return itk.array_from_image(projector.GetOutput()), seconds, cpu   # [view, row (down), column]

    def render(self, geom) -> tuple[np.ndarray, float, float]:
        """(image, seconds, CPU seconds)."""
        images, seconds, cpu = self._project([geom])
        return images[0], seconds, cpu

    def sweep(self, views) -> tuple[list[np.ndarray], float]:
        images, seconds, _ = self._project(list(views))
        return list(images), seconds
