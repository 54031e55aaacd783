# SPDX-License-Identifier: GPL-3.0-or-later

"""What differs between the Blenders PCVR supports (4.2 LTS to 5.3), one function per difference.

Each function tests for a feature, not a version number, so the releases in between get what they have.

| function             | difference                                                                     |
|----------------------|--------------------------------------------------------------------------------|
| `bundled_module`     | bpy 4.4 and later hide the bundled OpenImageIO; the bpy 4.2 package has none   |
| `set_file_format`    | 5.0 moved multi-layer OpenEXR from `file_format` to `media_type`               |
| `unregister_at_exit` | bpy 4.2 crashes and 4.5 hangs at exit unless the add-on lets go of bpy first   |
| `world_uses_nodes`   | 5.0 always renders a world through its nodes and deprecated World.use_nodes    |
| `composite_with`     | 5.0 composites through a node group; 5.3 lists it as one of the scene's effects |

5.1 to 5.3 changed nothing else that PCVR uses: render passes (RenderEngine.add_pass, register_pass),
volume grids (Volume.grids, VolumeGrid) and the image settings above behave as in 5.0, as `make
test-compat` checks with every add-on test and Blender's deprecation warnings made errors.
"""

import atexit
import importlib
import sys

import bpy


def bundled_module(name, package):
    """Blender's bundled Python module `name` (e.g. "OpenImageIO"), imported.

    Blender (the application) has its bundled modules on sys.path. Blender as a Python module (`bpy` from the
    package index) keeps them apart until bpy.utils.expose_bundled_modules(), which 4.4 added; bpy 4.2 ships
    the libraries but not their Python modules, so there the environment must provide one: `pip install
    package`."""
    expose = getattr(bpy.utils, "expose_bundled_modules", None)
    if expose is not None:
        expose()
    try:
        return importlib.import_module(name)
    except ImportError as ex:
        raise ImportError(f"Blender {bpy.app.version_string} bundles no Python module '{name}'; "
                          f"install it into this Python with `pip install {package}`") from ex


# Blender 5.0 chose multi-layer OpenEXR and video through ImageFormatSettings.media_type, which must be set
# before file_format offers them; earlier versions list them in file_format.
_MEDIA_TYPES = {'OPEN_EXR_MULTILAYER': 'MULTI_LAYER_IMAGE', 'FFMPEG': 'VIDEO'}


def set_file_format(image_settings, file_format):
    """Set `image_settings.file_format` to any format Blender writes (its 4.x identifiers), and on 5.0 the
    media type that offers it. Reading `file_format` needs no help: it gives those identifiers everywhere."""
    if "media_type" in image_settings.bl_rna.properties:
        image_settings.media_type = _MEDIA_TYPES.get(file_format, 'IMAGE')
    image_settings.file_format = file_format


def world_uses_nodes(world):
    """Whether `world` renders through its node tree (rather than its viewport colour). Before 5.0 its
    use_nodes chooses; 5.0 always uses the nodes, ignores use_nodes and warns when it is read."""
    if world.node_tree is None:
        return False
    if getattr(world.bl_rna.properties["use_nodes"], "is_deprecated", False):
        return True
    return world.use_nodes


def composite_with(scene, node_group):
    """Have `scene` composite its renders through `node_group` (a CompositorNodeTree ending in a Group Output),
    on Blender 5.0 and later. 5.0 to 5.2 take it as Scene.compositing_node_group; 5.3 deprecated that for
    Scene.compositor_effects, a stack of effects with a node group each (its first is what 5.2 had)."""
    prop = scene.bl_rna.properties.get("compositing_node_group")
    if prop is not None and not getattr(prop, "is_deprecated", False):
        scene.compositing_node_group = node_group
        return
    effects = scene.compositor_effects
    effects.clear()
    effects.new(name=node_group.name).node_group = node_group


def _blender_is_a_python_module():
    # bpy.app.module came with 4.4; before it, the module told itself apart by having no executable.
    return getattr(bpy.app, "module", not bpy.app.binary_path)


# Blender as a Python module shuts down (WM_exit) when finalisation frees one object: on 5.0 a capsule that
# is always freed, on 4.2 and 4.5 the bpy module itself, which is never freed while Blender holds anything
# that leads back to it. C++ static destructors then free what is left after the interpreter is gone, and
# 4.2 crashes (in PyGILState_Ensure, from ~SpaceType) while 4.5 waits for ever (in the destructor of its
# file-closing thread, which nothing told to stop). Two things of ours lead back to bpy: the classes Blender
# holds while they are registered, and, on 4.2 even after unregistering, the property callbacks (update=...),
# whose module globals hold `bpy`. So at exit the add-on is unregistered and then its modules' globals are
# cleared, as finalisation would clear them a moment later. Python runs its exit handlers last registered
# first, so both run before finalisation and before any handler added earlier. Inside the Blender
# application, Blender unregisters add-ons itself before Python ends: nothing is added there.

_PACKAGE = __name__.rpartition(".")[0]  # pcvr_addon, or bl_ext.REPOSITORY.pcvr as an extension
_registered_unregister = None


def unregister_at_exit(unregister):
    """Have Python call `unregister` at exit unless forget_at_exit() comes first, and then release the
    add-on's modules (see above). Called by register()."""
    global _registered_unregister
    if not _blender_is_a_python_module():
        return
    _registered_unregister = unregister
    for hook in (_release_modules, _unregister_at_exit):  # run in reverse order: unregister first
        atexit.unregister(hook)
        atexit.register(hook)


def forget_at_exit():
    """Called by unregister()."""
    global _registered_unregister
    _registered_unregister = None


def _unregister_at_exit():
    if _registered_unregister is None:
        return
    if _PACKAGE in bpy.context.preferences.addons:
        # Enabled as an add-on: disabling unregisters and tells Blender so, which then leaves it alone.
        import addon_utils
        addon_utils.disable(_PACKAGE)
    else:
        _registered_unregister()


def _release_modules():
    modules = [module for name, module in sys.modules.items()
               if module is not None and (name == _PACKAGE or name.startswith(_PACKAGE + "."))]
    for module in modules:  # this one's too: nothing below may look up a global
        module.__dict__.clear()
