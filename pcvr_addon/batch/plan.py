# SPDX-License-Identifier: GPL-3.0-or-later

"""Planning a batch: each Job read out of a Blender scene into plain values that any process can render.

The scene of a job is made exactly as `python -m pcvr_addon render` makes it (cli.command_scene.vdb_scene and
cli.command_scene.apply_options; a .blend opened as it is), once for all the jobs with the same scene and options;
each job then sets its frame and orbits the camera to its angle, and `scene.scene_inputs.read` takes what the render
engine's F12 would read (RenderInputs, DisplayInputs, the camera's view). Rendering those (render_task.py)
runs the engine's own prepare, render_raw and finish, which need no Blender data: so a worker with no scene
at all renders the same pixels as F12. The planner reads a scene's volume once, where `render` reads it to frame
it (a sequence's first frame); the workers read every image's.

A .vdb sequence is one scene, made from and framed on the first of its frames in the batch: the camera stays
put while it plays. Its other frames are not loaded into Blender (which would read every file whole on the
client): a frame's inputs are the first frame's from the same angle with the frame's file in place of the
first's, which is what Blender reads for that frame, since nothing else in the scene changes with the frame.
"""

import argparse
import dataclasses
import math
import os
from dataclasses import dataclass

import bpy
import numpy as np
from mathutils import Matrix, Vector

from .. import register, unregister
from ..cli import command_scene, drr
from ..render import prepared_scene
from ..scene import camera, scene_inputs
from .jobs import Job


@dataclass(frozen=True)
class PlannedJob:
    job: Job
    index: int                               # in the batch, for the manifest
    inputs: scene_inputs.RenderInputs
    display: scene_inputs.DisplayInputs
    view: camera.CameraView


class PlanError(ValueError):
    """A job that cannot be planned: its input cannot be read or makes no image."""


def options_namespace(options, defaults):
    """argparse.Namespace of the render options `options` (cli option names with '_') over `defaults`."""
    unknown = options.keys() - vars(defaults).keys()
    if unknown:
        raise PlanError(f"unknown render options {sorted(unknown)}")
    return argparse.Namespace(**{**vars(defaults), **options})


def plan(jobs, defaults, stream_above_mib, start_index=0):
    """PlannedJob of each Job (in order), reading each scene once. `defaults`: the render options not given
    (an argparse.Namespace of cli's render command); `stream_above_mib`: the stream threshold every job
    renders with (resolved here, not on the workers, so that every process streams the same volumes).
    Raises PlanError naming the job's input."""
    planned = []
    by_scene = {}
    for index, job in enumerate(jobs):
        by_scene.setdefault(job.scene_key, []).append((start_index + index, job))
    register()
    try:
        for scene_jobs in by_scene.values():
            planned.extend(_plan_scene(scene_jobs, defaults, stream_above_mib))
    finally:
        unregister()
    return sorted(planned, key=lambda p: p.index)


def _plan_scene(indexed_jobs, defaults, stream_above_mib):
    first = indexed_jobs[0][1]
    scene_file = first.scene or first.input
    args = options_namespace(first.options, defaults)
    if args.stream_above is None:
        args.stream_above = stream_above_mib
    args.frame = None  # each job sets its own
    bpy.ops.wm.read_factory_settings(use_empty=True)
    path = os.path.abspath(scene_file)
    if not os.path.isfile(path):
        raise PlanError(f"'{scene_file}' does not exist")
    if path.lower().endswith(".blend"):
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    scene = bpy.context.scene
    if path.lower().endswith(".vdb"):
        try:
            command_scene.vdb_scene(scene, path, grid=args.grid,
                          magnification=args.magnification or command_scene.DEFAULT_MAGNIFICATION,
                          light_direction=args.light_direction or command_scene.DEFAULT_LIGHT_DIRECTION)
        except RuntimeError as ex:
            raise PlanError(str(ex)) from None
    command_scene.apply_options(scene, args)
    if scene.camera is None:
        raise PlanError(f"'{first.input}': the scene has no camera")
    sweep = any(job.angle is not None for _index, job in indexed_jobs)
    if args.cone_beam is not None:
        try:
            drr.c_arm_view(scene, vars(args))
        except RuntimeError as ex:
            raise PlanError(f"'{first.input}': {ex}") from None
        orbit = _GantrySweep(scene, vars(args)) if sweep else None
    else:
        orbit = _Orbit(scene) if sweep else None
    is_vdb = path.lower().endswith(".vdb")
    read_at = {}  # a .vdb's inputs by angle, read at its scene's own frame
    planned = []
    for index, job in indexed_jobs:
        if is_vdb:
            if job.angle not in read_at:
                read_at[job.angle] = _read(scene, orbit, job)
            inputs, display, view = read_at[job.angle]
            inputs = _with_file(inputs, path, os.path.abspath(job.input))
        else:
            if job.frame is not None and scene.frame_current != job.frame:
                scene.frame_set(job.frame)
            inputs, display, view = _read(scene, orbit, job)
        planned.append(PlannedJob(job, index, inputs, display, view))
    return planned


def _read(scene, orbit, job):
    """What F12 would read of the scene at the job's angle: (RenderInputs, DisplayInputs, CameraView)."""
    if orbit is not None:
        orbit.turn(job.angle or 0.0)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    depsgraph.update()
    view = camera.scene_view(depsgraph)
    inputs, display = scene_inputs.read(depsgraph, prepared_scene.export_grid, view)
    if any(volume.grid is not None for volume in inputs.volumes):
        raise PlanError(f"'{job.input}': a procedural volume (made by modifiers or geometry nodes) lives only "
                        "in Blender; render this scene with `blender -b FILE -E PCVR -a` instead")
    return inputs, display, view


def _with_file(inputs, scene_file, frame_file):
    """RenderInputs with the volume read from `scene_file` read from `frame_file` instead."""
    if frame_file == scene_file:
        return inputs
    scene_real = os.path.realpath(scene_file)
    volumes = tuple(dataclasses.replace(volume, filepath=frame_file)
                    if volume.filepath and os.path.realpath(volume.filepath) == scene_real else volume
                    for volume in inputs.volumes)
    if volumes == inputs.volumes:
        raise PlanError(f"'{scene_file}': no volume of its scene reads it, so its frames cannot stand in for it")
    return dataclasses.replace(inputs, volumes=volumes)


class _Orbit:
    """Turns the scene camera about the axis through the volumes' centre along the camera's own up direction
    (a C-arm about its patient): angle 0 is the camera as it is, positive angles turn it counter-clockwise
    seen from above that axis. Its clip range grows to hold the volumes' bounding sphere from every side."""

    def __init__(self, scene):
        self.camera = scene.camera
        self.start = self.camera.matrix_world.copy()
        corners = [obj.matrix_world @ Vector(corner) for obj in scene.objects if obj.type == 'VOLUME'
                   for corner in obj.bound_box]
        if not corners:
            raise PlanError("--angles: the scene has no volume to orbit about")
        lo = Vector(np.min(corners, axis=0))
        hi = Vector(np.max(corners, axis=0))
        self.centre = (lo + hi) / 2
        self.axis = (self.start.to_3x3() @ Vector((0.0, 1.0, 0.0))).normalized()
        radius = (hi - lo).length / 2
        data = self.camera.data
        if data.type == 'ORTHO':
            # An orthographic image does not change as the camera backs away along its view: back it away
            # until the sphere lies between its clip planes.
            eye = self.start.translation
            forward = -(self.start.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()
            along = (self.centre - eye).dot(forward)
            backed = max(along, radius + data.clip_start * 2)
            self.start = Matrix.Translation(forward * (along - backed)) @ self.start
            data.clip_end = max(data.clip_end, backed + radius + data.clip_start)

    def turn(self, degrees):
        about_centre = (Matrix.Translation(self.centre) @ Matrix.Rotation(math.radians(degrees), 4, self.axis)
                        @ Matrix.Translation(-self.centre))
        self.camera.matrix_world = about_centre @ self.start


class _GantrySweep:
    """Turns a C-arm's gantry (--cone-beam): the angle is the gantry's, in degrees (cli.drr.c_arm_view)."""

    def __init__(self, scene, options):
        self.scene, self.options = scene, options

    def turn(self, degrees):
        drr.c_arm_view(self.scene, self.options, gantry=degrees)
