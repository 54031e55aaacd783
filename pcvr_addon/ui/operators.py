# SPDX-License-Identifier: GPL-3.0-or-later

import bpy
import numpy as np
from bl_operators.presets import AddPresetBase
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty
from bpy.types import Operator
from mathutils import Matrix

from ..render import prepared_scene
from ..scene import camera, clipping, first_look, transfer_function
from ..scene.volumes import KERNEL_RADIUS_VOXELS
from . import presets


def volume_grid(operator, context, obj):
    """The world-space grid of the volume object `obj`, or None after `operator` reported why there is none."""
    if obj is None or obj.type != 'VOLUME':
        operator.report({'ERROR'}, "The active object is not a volume")
        return None
    try:
        grid = prepared_scene.object_grid(context.evaluated_depsgraph_get(), obj)
    except (OSError, ValueError, RuntimeError, MemoryError, ImportError) as ex:
        operator.report({'ERROR'}, f"Volume object '{obj.name}': {ex}")
        return None
    if grid.active_voxel_count == 0:
        operator.report({'ERROR'}, f"Volume object '{obj.name}' has no active voxels")
        return None
    return grid


class PCVR_OT_frame_volume(Operator):
    """Point the scene camera at the active volume, orthographic, from one of Blender's axis views (the front by
    default), the whole volume in the image at the scene's resolution (or, with Set Resolution, the resolution
    that gives one voxel the given number of pixels)"""
    bl_idname = "pcvr.frame_volume"
    bl_label = "Frame Volume"
    bl_options = {'REGISTER', 'UNDO'}

    set_resolution: BoolProperty(
        name="Set Resolution",
        description="Change the scene's resolution so that one voxel spans Magnification pixels (off: keep the "
                    "resolution and fit the volume in it)",
        default=False,
    )
    magnification: FloatProperty(
        name="Magnification",
        description="Pixels per voxel (with Set Resolution)",
        min=0.01, soft_min=0.25, soft_max=32.0,
        default=4.0,
    )
    view: EnumProperty(
        name="View",
        description="Where the camera looks from, as Blender's numpad views (a scan in LPS faces the front)",
        items=[(key, key.title() if key != 'ISO' else "Isometric", "") for key in camera.AXIS_VIEWS] +
              [('DIRECTION', "Direction", "Along View Direction")],
        default='FRONT',
    )
    direction: FloatVectorProperty(
        name="View Direction",
        description="The direction the camera looks along, in world space (View: Direction)",
        size=3, default=(0.0, 0.0, -1.0),
    )

    def execute(self, context):
        grid = volume_grid(self, context, context.active_object)
        if grid is None:
            return {'CANCELLED'}
        try:
            look, up = camera.AXIS_VIEWS[self.view] if self.view in camera.AXIS_VIEWS else (self.direction, None)
            rotation = camera.look_rotation(look, up)
        except ValueError as ex:
            self.report({'ERROR'}, f"Frame Volume: {ex}")
            return {'CANCELLED'}

        index_to_world = np.asarray(grid.index_to_world)
        # Pixels follow the grid's first axis; the image is exact for grids aligned with the view's axes.
        voxel_size = float(np.linalg.norm(index_to_world[:3, 0]))
        # The voxels' box in the camera's axes: image x, image y, and towards the camera.
        corners = _world_corners(index_to_world, *grid.index_bbox) @ rotation
        lo, hi = corners.min(axis=0), corners.max(axis=0)

        # Room for the splat kernels of the outermost voxels on every side.
        margin = 2 * KERNEL_RADIUS_VOXELS * voxel_size
        extent = hi[:2] - lo[:2] + margin
        depth = hi[2] - lo[2]

        scene = context.scene
        render = scene.render
        if self.set_resolution:
            width, height = (max(1, round(size / voxel_size * self.magnification)) for size in extent)
            render.resolution_x, render.resolution_y = width, height
            render.resolution_percentage = 100
            render.pixel_aspect_x = render.pixel_aspect_y = 1.0
            ortho_scale = max(width, height) / self.magnification * voxel_size
        else:
            ortho_scale = _fitting_ortho_scale(render, extent)

        camera_object = _scene_camera(context)
        cam = camera_object.data
        cam.type = 'ORTHO'
        cam.sensor_fit = 'AUTO'  # ortho_scale spans the larger side of the image
        cam.ortho_scale = ortho_scale
        cam.shift_x = cam.shift_y = 0.0
        # Every voxel centre must lie between the clip planes.
        cam.clip_start = margin
        cam.clip_end = 3 * margin + depth
        eye = (lo + hi) / 2
        eye[2] = hi[2] + 2 * margin
        placement = Matrix(rotation.tolist()).to_4x4()
        placement.translation = rotation @ eye
        camera_object.matrix_world = placement
        first_look.aim_scan_light(scene, add=False)
        first_look.show_xray_plainly(scene)
        return {'FINISHED'}


class PCVR_OT_c_arm_view(Operator):
    """Make the scene camera a C-arm's: a cone-beam radiograph (DRR) of the active volume from an X-ray source at
    Source to Isocentre from the volume's centre, on a flat detector at Source to Detector from the source
    (pcvr_native.cameras.cone_beam's geometry; lengths in millimetres, angles in degrees)"""
    bl_idname = "pcvr.c_arm_view"
    bl_label = "C-Arm View"
    bl_options = {'REGISTER', 'UNDO'}

    sad: FloatProperty(name="Source to Isocentre", description="Distance from the X-ray source to the isocentre, "
                       "millimetres (SAD)", min=1e-3, soft_max=2000.0, default=1000.0)
    sid: FloatProperty(name="Source to Detector", description="Distance from the X-ray source to the detector, "
                       "millimetres (SID), more than Source to Isocentre", min=1e-3, soft_max=3000.0, default=1500.0)
    detector_cols: IntProperty(name="Detector Columns", description="Pixels across the detector (the image's width)",
                               min=1, max=1 << 16, soft_max=4096, default=512)
    detector_rows: IntProperty(name="Detector Rows", description="Pixels down the detector (the image's height)",
                               min=1, max=1 << 16, soft_max=4096, default=512)
    pixel_spacing: FloatVectorProperty(name="Pixel Spacing", description="A detector pixel's width and height, "
                                       "millimetres", size=2, min=1e-6, soft_max=5.0, default=(0.8, 0.8))
    gantry: FloatProperty(name="Gantry Angle", description="Degrees about the world's Z axis: 0 puts the source in "
                          "front (-Y, anterior for a scan in LPS), 90 at +X (the patient's left)", default=0.0)
    tilt: FloatProperty(name="Tilt", description="Degrees the source turns towards +Z out of the gantry's plane",
                        default=0.0)
    detector_offset: FloatVectorProperty(name="Detector Offset", description="The detector's centre moved right and "
                                         "up in the image, millimetres", size=2, default=(0.0, 0.0))
    use_isocentre: BoolProperty(name="Set Isocentre", description="Aim at Isocentre instead of the active volume's "
                                "centre", default=False)
    isocentre: FloatVectorProperty(name="Isocentre", description="World position the central ray passes through, "
                                   "millimetres (with Set Isocentre)", size=3, default=(0.0, 0.0, 0.0))

    def execute(self, context):
        from pcvr_native.cameras import cone_beam

        scene = context.scene
        # World units per millimetre: one metre per unit, times the scene's Unit Scale (0.001: a unit a millimetre).
        unit = 0.001 / scene.unit_settings.scale_length
        if self.use_isocentre:
            isocentre = np.asarray(self.isocentre)
        else:
            grid = volume_grid(self, context, context.active_object)
            if grid is None:
                return {'CANCELLED'}
            lo, hi = np.asarray(grid.index_bbox, dtype=np.float64)
            isocentre = (grid.index_to_world @ np.append((lo + hi) / 2, 1.0))[:3] / unit
        du, dv = self.pixel_spacing
        try:  # in millimetres, so that its errors say what the user typed
            cone = cone_beam(self.sad, self.sid, (self.detector_cols, self.detector_rows), (du, dv), isocentre,
                             self.gantry, self.tilt, self.detector_offset)
        except ValueError as ex:
            self.report({'ERROR'}, f"C-Arm View: {ex}")
            return {'CANCELLED'}
        if not max(du, dv) <= 200 * min(du, dv):
            self.report({'ERROR'}, f"C-Arm View: Blender's pixel aspect goes to 200, not {du} x {dv} mm pixels")
            return {'CANCELLED'}
        render = scene.render
        render.resolution_x, render.resolution_y = self.detector_cols, self.detector_rows
        render.resolution_percentage = 100
        render.pixel_aspect_x, render.pixel_aspect_y = du / min(du, dv), dv / min(du, dv)
        camera_object = _scene_camera(context)
        _c_arm_lens(camera_object.data, self.sid, (self.detector_cols * du, self.detector_rows * dv),
                    self.detector_offset)
        # cone_beam's clip range, in which every voxel from the source's side to past the detector is imaged.
        camera_object.data.clip_start, camera_object.data.clip_end = 0.01 * self.sad * unit, 100.0 * self.sid * unit
        placement = np.linalg.inv(cone.world_to_camera)
        placement[:3, 3] *= unit
        camera_object.matrix_world = Matrix(placement.tolist())
        first_look.aim_scan_light(scene, add=False)
        first_look.show_xray_plainly(scene)
        return {'FINISHED'}


def _c_arm_lens(cam, sid, detector_size, detector_offset):
    """A perspective camera whose focal length and sensor (the side the detector's aspect fits) are the source to
    detector distance and the detector's size (millimetres: only their ratio counts), shifted by the offset."""
    width, height = detector_size
    fit_width = width >= height
    # Blender keeps the focal length and sensor at 1 mm or more.
    scale = max(1.0, 1.0 / min(sid, width if fit_width else height))
    cam.type = 'PERSP'
    cam.lens_unit = 'MILLIMETERS'
    cam.lens = sid * scale
    cam.sensor_fit = 'HORIZONTAL' if fit_width else 'VERTICAL'
    if fit_width:
        cam.sensor_width = width * scale
    else:
        cam.sensor_height = height * scale
    # Shifts count in the fitted side.
    cam.shift_x, cam.shift_y = (offset / (width if fit_width else height) for offset in detector_offset)


def _fitting_ortho_scale(render, extent):
    """The ortho_scale (sensor fit 'AUTO': it spans the larger side of the image, pixel aspect included) at which
    `extent` (width, height in world units) just fits in the scene's image."""
    sides = (render.resolution_x * render.pixel_aspect_x, render.resolution_y * render.pixel_aspect_y)
    return max(size * max(sides) / side for size, side in zip(extent, sides))


def _world_corners(index_to_world, index_min, index_max):
    """World-space corners (8, 3) of the voxels from index_min to index_max (inclusive), cells included."""
    lo, hi = np.asarray(index_min) - 0.5, np.asarray(index_max) + 0.5
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return (index_to_world @ corners.T)[:3].T


def _scene_camera(context):
    """The scene camera, created when the scene has none."""
    scene = context.scene
    if scene.camera is not None and scene.camera.type == 'CAMERA':
        return scene.camera
    camera_object = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera_object)
    scene.camera = camera_object
    return camera_object


class VolumeOperator:
    @classmethod
    def poll(cls, context):
        return getattr(context, "volume", None) is not None


class RampTextureNew(VolumeOperator):
    """The New button of a ramp texture the volume's settings point to (their member `ramp_texture`): a copy of
    the one it has, or one holding the default ramp (the settings' ensure_<ramp_texture>)."""
    bl_options = {'REGISTER', 'UNDO'}
    ramp_texture = ""

    def execute(self, context):
        settings = context.volume.pcvr
        texture = getattr(settings, self.ramp_texture)
        if texture is not None:
            setattr(settings, self.ramp_texture, texture.copy())
        else:
            getattr(settings, f"ensure_{self.ramp_texture}")()
        return {'FINISHED'}


class PCVR_OT_transfer_function_new(RampTextureNew, Operator):
    """Give the volume a transfer function of its own: a copy of the one it has, or the default grey ramp"""
    bl_idname = "pcvr.transfer_function_new"
    bl_label = "New Transfer Function"
    ramp_texture = "transfer_function"


class PCVR_OT_gradient_opacity_new(RampTextureNew, Operator):
    """Give the volume a gradient-opacity ramp of its own: a copy of the one it has, or the default"""
    bl_idname = "pcvr.gradient_opacity_new"
    bl_label = "New Gradient Opacity"
    ramp_texture = "gradient_opacity"


class FromGridOperator(VolumeOperator):
    """Sets the active volume's settings from what its grid holds now (`apply`), read through the cache."""
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        grid = volume_grid(self, context, context.object)
        if grid is None:
            return {'CANCELLED'}
        self.apply(context.object.data.pcvr, grid)
        return {'FINISHED'}


class PCVR_OT_transfer_function_range_from_grid(FromGridOperator, Operator):
    """Spread the colour ramp over the values the volume's grid holds now (times the density scale), from 0
    or its lowest value to its highest"""
    bl_idname = "pcvr.transfer_function_range_from_grid"
    bl_label = "Range from Grid Values"

    @staticmethod
    def apply(settings, grid):
        settings.tf_min, settings.tf_max = transfer_function.grid_range(grid.value_range, settings.density_scale)
        settings.use_grid_range = False


class PCVR_OT_gradient_max_from_grid(FromGridOperator, Operator):
    """Set Max Gradient to that of a sharp edge across the whole range of the volume's grid (times the density
    scale): the steepest boundaries reach the ramp's right end"""
    bl_idname = "pcvr.gradient_max_from_grid"
    bl_label = "Max Gradient from Grid"

    @staticmethod
    def apply(settings, grid):
        settings.gradient_max = transfer_function.edge_gradient(grid.value_range, settings.density_scale,
                                                                grid.index_to_world)


class PCVR_OT_transfer_function_preset_add(VolumeOperator, AddPresetBase, Operator):
    """Save the volume's transfer function and material as a preset, or remove the preset chosen last"""
    bl_idname = "pcvr.transfer_function_preset_add"
    bl_label = "Add Transfer Function Preset"
    preset_menu = "PCVR_PT_transfer_function_presets"
    preset_subdir = presets.SUBDIR

    def add(self, context, filepath):
        presets.write(context.volume.pcvr, filepath)


class VolumeObjectOperator:
    """An operator on the active volume object (in the Properties editor, the one it shows)."""
    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == 'VOLUME'


def _local_bounds(operator, context, obj):
    """(centre, half sizes) of the volume object's bounding box in its own space, or None after `operator`
    reported why there is none."""
    corners = np.array([tuple(corner) for corner in obj.evaluated_get(context.evaluated_depsgraph_get()).bound_box])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    if not (hi > lo).any():
        operator.report({'ERROR'}, f"Volume object '{obj.name}' has no extent: its grids are empty or not loaded")
        return None
    return (lo + hi) / 2, (hi - lo) / 2


def _add_helper_empty(context, volume_object, name, display_type, location, scale, size=1.0):
    """clipping.add_empty as a child of `volume_object` (it moves with the volume) at `location` in the volume's
    space, in the volume's collection, and the only object selected and active (to be moved right away)."""
    collection = volume_object.users_collection[0] if volume_object.users_collection else context.scene.collection
    empty = clipping.add_empty(collection, name, display_type, size, parent=volume_object)
    empty.location, empty.scale = location, scale
    for obj in context.selected_objects:
        obj.select_set(False)
    empty.select_set(True)
    context.view_layer.objects.active = empty
    return empty


class AddClipObject(VolumeObjectOperator):
    """Adds an empty fitted to the active volume object's bounding box, (centre, half sizes) in its space, and
    makes it cut the volume (`add`)."""
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        obj = context.object
        bounds = _local_bounds(self, context, obj)
        if bounds is None:
            return {'CANCELLED'}
        self.add(context, obj, *bounds)
        return {'FINISHED'}


class PCVR_OT_add_crop_box(AddClipObject, Operator):
    """Add an empty drawn as a cube around the volume, and crop the volume to it: move, turn and scale the cube
    to keep the part of the volume inside it"""
    bl_idname = "pcvr.add_crop_box"
    bl_label = "Add Crop Box"

    def add(self, context, obj, centre, half):
        # An empty cube of size 1 draws its local [-1, 1]^3: exactly the box a crop object keeps.
        box = _add_helper_empty(context, obj, f"{obj.name} Crop", 'CUBE', centre, np.maximum(half, 1e-6 * half.max()))
        settings = obj.data.pcvr
        settings.crop_object, settings.use_crop = box, True


class PCVR_OT_add_clip_plane(AddClipObject, Operator):
    """Add an empty through the volume's centre and cut the volume at its XY plane, keeping the side its arrow
    (local +Z) points to"""
    bl_idname = "pcvr.add_clip_plane"
    bl_label = "Add Clip Plane"

    def add(self, context, obj, centre, half):
        plane = _add_helper_empty(context, obj, f"{obj.name} Clip Plane", 'SINGLE_ARROW', centre, (1.0, 1.0, 1.0),
                                  size=float(np.linalg.norm(half)))
        settings = obj.data.pcvr
        settings.clip_planes.add().object = plane
        settings.clip_plane_index = len(settings.clip_planes) - 1


class PCVR_OT_remove_clip_plane(VolumeOperator, Operator):
    """Stop cutting the volume at the chosen clip plane (its object stays)"""
    bl_idname = "pcvr.remove_clip_plane"
    bl_label = "Remove Clip Plane"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return super().poll(context) and len(context.volume.pcvr.clip_planes) > 0

    def execute(self, context):
        settings = context.volume.pcvr
        settings.clip_planes.remove(settings.clip_plane_index)
        settings.clip_plane_index = max(0, min(settings.clip_plane_index, len(settings.clip_planes) - 1))
        context.volume.update_tag()  # a collection's items change without an update callback
        return {'FINISHED'}


classes = (
    PCVR_OT_frame_volume,
    PCVR_OT_c_arm_view,
    PCVR_OT_transfer_function_new,
    PCVR_OT_transfer_function_range_from_grid,
    PCVR_OT_transfer_function_preset_add,
    PCVR_OT_gradient_opacity_new,
    PCVR_OT_gradient_max_from_grid,
    PCVR_OT_add_crop_box,
    PCVR_OT_add_clip_plane,
    PCVR_OT_remove_clip_plane,
)


register, unregister = bpy.utils.register_classes_factory(classes)
