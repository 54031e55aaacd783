"""PCVR native core: post-convolved splatting of OpenVDB volumes.

See CONTRACT section 1: read_vdb, list_grids, Grid, Camera, render_xray.
"""

from ._pcvr import *  # noqa: F401,F403
from ._pcvr import __doc__  # noqa: F401
