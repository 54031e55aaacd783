"""A render-farm worker's render, as `blender -b SCENE -E PCVR -s FIRST -e LAST -a` runs it, on a machine that
has only Blender and the PCVR extension: install the extension zip into a fresh user folder (as
`blender --command extension install-file` does), open the .blend and render its animation.

Run by test_render_farm.py in a fresh process whose BLENDER_USER_RESOURCES is a temporary folder and whose
sys.path does not hold this repository:

    python farm_render.py ARCHIVE WORK_DIR SCENE.blend FIRST LAST
"""

import sys
from pathlib import Path

import bpy

MODULE = "bl_ext.farm.pcvr"


def main(archive, work_dir, blend, first, last):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    repos = bpy.context.preferences.extensions.repos
    repos.new(name="Farm", module="farm", custom_directory=str(work_dir / "repo"), source='USER')
    bpy.ops.extensions.package_install_files(filepath=str(archive), repo="farm", enable_on_install=True)
    assert MODULE in bpy.context.preferences.addons, "the extension was installed but not enabled"

    bpy.ops.wm.open_mainfile(filepath=str(blend), load_ui=False)
    scene = bpy.context.scene
    scene.render.engine = 'PCVR'  # -E PCVR
    scene.frame_start, scene.frame_end = first, last  # -s FIRST -e LAST
    bpy.ops.render.render(animation=True)  # -a
    assert f"{MODULE}.engine" in sys.modules, "the render did not go through the installed extension"
    assert "pcvr_addon" not in sys.modules, "the repository's add-on was imported: not a farm worker's setup"
    print("rendered frames", first, "to", last)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
