# SPDX-License-Identifier: GPL-3.0-or-later

"""PCVR: X-ray images of OpenVDB volumes by post-convolved splatting, as a Blender render engine."""

import bpy

from . import compat, engine


class PCVRRenderEngine(bpy.types.RenderEngine):
    bl_idname = "PCVR"
    bl_label = "PCVR"
    bl_use_postprocess = True
    bl_use_preview = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)

    def render(self, depsgraph):
        engine.render(self, depsgraph)

    def update_render_passes(self, scene, view_layer):
        engine.register_passes(self, scene, view_layer)


classes = (
    PCVRRenderEngine,
)


def register():
    from . import operators, properties, ui

    properties.register()
    operators.register()
    ui.register()
    for cls in classes:
        bpy.utils.register_class(cls)
    compat.unregister_at_exit(unregister)


def unregister():
    from . import operators, properties, ui

    compat.forget_at_exit()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    ui.unregister()
    operators.unregister()
    properties.unregister()
