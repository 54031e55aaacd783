"""Install the packaged extension the way Blender's Extensions preferences do, enable it and render.

Run by test_extension.py in a fresh process whose BLENDER_USER_RESOURCES points at a temporary
folder, so nothing lands in the user's own Blender configuration:

    python install_extension.py ARCHIVE WORK_DIR [--leave-enabled]

--leave-enabled ends the script with the extension still enabled, as a user's script would.

install() serves tests/portable/render_here.py too.
"""

import sys
from pathlib import Path

import bpy

MODULE = "bl_ext.pcvr_test.pcvr"


def install(archive, work_dir):
    """Install and enable the extension `archive` in a new user repository under `work_dir` (Blender picks
    the wheels that fit its Python); return the add-on's module."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    repos = bpy.context.preferences.extensions.repos
    repos.new(name="PCVR Test", module="pcvr_test", custom_directory=str(work_dir / "repo"), source='USER')
    bpy.ops.extensions.package_install_files(filepath=str(archive), repo="pcvr_test", enable_on_install=True)
    assert MODULE in bpy.context.preferences.addons, "the extension was installed but not enabled"
    return sys.modules[MODULE]


def main(archive, work_dir, leave_enabled):
    install(archive, work_dir)
    # The scene helpers import pcvr_native, which the installed extension provides.
    import numpy as np
    import blender_scenes as bs
    import lit_scenes as ls

    scene = bs.setup(48, 40)
    bs.add_camera(location=(0.2, -3.0, 1.0), lens=35.0, rotation=(1.25, 0.0, 0.05))
    obj = bs.add_volume("Blob", bs.write_vdb(work_dir / "blob.vdb", bs.blob(np.random.default_rng(7))))
    bs.assert_matches(bs.xray(bs.render(scene)), bs.exact(bs.world_grid(obj)))
    assert f"{MODULE}.engine" in sys.modules, "the render did not go through the installed extension"

    # Shaded, with a preset that the extension ships.
    assert Path(sys.modules[f"{MODULE}.ui.presets"].find("Cloud")).is_relative_to(work_dir / "repo")
    obj.data.pcvr.apply_preset("Cloud")
    scene.pcvr.mode = 'SHADED'
    ls.add_light('SUN', power=3.0)
    assert ls.combined(bs.render(scene))[..., 3].max() > 0.5

    if not leave_enabled:
        bpy.ops.preferences.addon_disable(module=MODULE)
    print("installed, enabled and rendered")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), "--leave-enabled" in sys.argv[3:])
