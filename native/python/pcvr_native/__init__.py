"""PCVR native core: post-convolved splatting of OpenVDB volumes.

See CONTRACT section 1: read_vdb, list_grids, Grid, Camera, render_xray.
"""

from . import _cpu

_cpu.check()  # before the compiled module loads: it may use instructions this CPU does not have

from ._pcvr import *  # noqa: E402,F401,F403
from ._pcvr import __doc__  # noqa: E402,F401
