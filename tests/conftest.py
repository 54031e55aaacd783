"""Test setup shared by every suite: the repository root on sys.path (for pcvr_addon), a seeded
random generator, and a fresh Blender for every add-on test. The native tests never import bpy.

(tests/addon has no conftest.py of its own: the native tests import theirs as the module `conftest`,
which a second one would shadow.)"""

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
ADDON_TESTS = ROOT / "tests" / "addon"
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture
def rng():
    return np.random.default_rng(20250101)


@pytest.fixture(autouse=True)
def blender(request):
    """For tests under tests/addon: Blender reset to factory settings with an empty scene, pcvr_addon
    registered and its grid cache emptied; unregistered afterwards."""
    if ADDON_TESTS not in Path(request.node.path).parents:
        yield None
        return
    import bpy
    import pcvr_addon
    from pcvr_addon.render import cache

    bpy.ops.wm.read_factory_settings(use_empty=True)
    cache.grids.clear()
    pcvr_addon.register()
    yield bpy
    pcvr_addon.unregister()
