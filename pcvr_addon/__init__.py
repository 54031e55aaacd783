# SPDX-License-Identifier: GPL-3.0-or-later

"""PCVR: X-ray images of OpenVDB volumes by post-convolved splatting, as a Blender render engine."""

import bpy

from . import compat, engine
from .render import passes, viewport_session


class PCVRRenderEngine(bpy.types.RenderEngine):
    bl_idname = "PCVR"
    bl_label = "PCVR"
    bl_use_postprocess = True
    bl_use_preview = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.viewport_session = None

    # A class attribute, so that __del__ still finds it when Python clears the modules' globals at exit.
    _free_viewport = staticmethod(viewport_session.free)

    def __del__(self):
        # Blender frees a viewport's engine when it leaves Rendered shading: stop the session's worker thread.
        self._free_viewport(self)

    def render(self, depsgraph):
        engine.render(self, depsgraph)

    def update_render_passes(self, scene, view_layer):
        passes.register_passes(self, scene, view_layer)

    def view_update(self, context, depsgraph):
        viewport_session.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport_session.view_draw(self, context, depsgraph)


classes = (
    PCVRRenderEngine,
)


def register():
    from .ui import operators, panels, properties
    from .io import import_volume

    properties.register()
    operators.register()
    import_volume.register()
    panels.register()
    for cls in classes:
        bpy.utils.register_class(cls)
    compat.unregister_at_exit(unregister)


def unregister():
    from .ui import operators, panels, properties
    from .io import import_volume

    compat.forget_at_exit()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    panels.unregister()
    import_volume.unregister()
    operators.unregister()
    properties.unregister()
