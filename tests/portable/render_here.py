"""Install the extension zip as Blender does and render with it through F12 and the command line:

    python render_here.py ARCHIVE WORK_DIR

Run by test_portable_root.py twice, with the same code and inputs: on the build machine and inside the
Debian 13 root file system. WORK_DIR holds this script and the test helpers it imports
(install_extension, blender_scenes, lit_scenes, tools/ct_head.py), nothing else of the checkout: the
add-on and pcvr_native come from the archive. Writes WORK_DIR/out/images.npz (every image, float32) and
WORK_DIR/out/ldd.txt (what the loader found for pcvr_native's module).
"""

import hashlib
import io
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import bpy

import install_extension

CT_BONE = "CT Bone"


def shipped_wheel(names):
    """Of an archive's file names, the pcvr_native wheel for this Python (the one Blender installs)."""
    tag = "cp{}{}".format(*sys.version_info[:2])
    [wheel] = [name for name in names if name.startswith("wheels/pcvr_native-") and f"-{tag}-" in name]
    return wheel


def shipped_module_digest(archive):
    """SHA-256 of the compiled module in the archive's wheel for this Python."""
    with zipfile.ZipFile(archive) as extension:
        wheel = extension.read(shipped_wheel(extension.namelist()))
    with zipfile.ZipFile(io.BytesIO(wheel)) as files:
        [module] = [name for name in files.namelist() if name.startswith("pcvr_native/_pcvr")]
        return hashlib.sha256(files.read(module)).hexdigest()


def install_shipped_wheel(archive, work):
    """The archive's add-on and its wheel for this Python installed beside bpy, as the command line
    needs them (Blender removes an extension's wheels from its own folder when a process starts
    with the extension not enabled)."""
    with zipfile.ZipFile(archive) as extension:
        names = extension.namelist()
        extension.extractall(work / "addon" / "pcvr_addon", [name for name in names
                                                              if not name.startswith("wheels/")])
        wheel = shipped_wheel(names)
        extension.extract(wheel, work)
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--target",
                    str(work / "site"), str(work / wheel)], check=True)


def cli_render(work, volume, out, *options):
    """`python -m pcvr_addon render`, with the archive's add-on and wheel and no Blender configuration."""
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join([str(work / "addon"), str(work / "site")]),
                       BLENDER_USER_RESOURCES=str(work / "command-line"))
    subprocess.run([sys.executable, "-m", "pcvr_addon", "render", str(volume), "-o", str(out),
                    "--magnification", "2", *options], env=environment, check=True, timeout=300)


def main(archive, work):
    out = work / "out"
    out.mkdir()
    install_extension.install(archive, work)
    import numpy as np
    import pcvr_native

    # The archive's module (Blender's copy of it; here, pip's from the same wheel may come first on sys.path).
    module = Path(pcvr_native.__file__).parent
    [shared_object] = module.glob("_pcvr*.so")
    assert hashlib.sha256(shared_object.read_bytes()).hexdigest() == shipped_module_digest(archive), \
        f"{shared_object} is not the module that {archive.name} ships"
    (out / "ldd.txt").write_text(subprocess.run(["ldd", str(shared_object)], capture_output=True,
                                                text=True, check=True).stdout)

    install_shipped_wheel(archive, work)
    sys.path.append(str(work / "addon"))  # the helpers import pcvr_addon.io.image_io
    import blender_scenes as bs
    import lit_scenes as ls
    from pcvr_addon.io import image_io

    # F12: a smooth blob in X-ray (densities 0 to 1.5), then the CT head in Hounsfield units, shaded.
    images = {}
    scene, head = ls.head_scene(work)
    blob = bs.add_volume("Blob", bs.write_vdb(work / "blob.vdb", bs.blob(np.random.default_rng(7))),
                         scale=(8.0, 8.0, 8.0))
    head.hide_render = True
    scene.pcvr.mode = 'XRAY'
    bpy.context.view_layer.pcvr.use_pass_xray = True
    images["f12_xray"] = bs.xray(bs.render(scene))
    head.hide_render, blob.hide_render = False, True
    scene.pcvr.mode = 'SHADED'
    head.data.pcvr.apply_preset(CT_BONE)
    images["f12_shaded"] = ls.combined(bs.render(scene))

    cli_render(work, work / "blob.vdb", out / "cli_xray.exr")
    cli_render(work, work / "head.vdb", out / "cli_shaded.exr", "--mode", "shaded", "--preset", CT_BONE)
    for name in ("cli_xray", "cli_shaded"):
        images[name] = image_io.read_passes(str(out / f"{name}.exr"))[""]
    np.savez(out / "images.npz", **{name: np.asarray(image, np.float32) for name, image in images.items()})
    print("rendered", ", ".join(images))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
