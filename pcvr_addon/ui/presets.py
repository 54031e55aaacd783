# SPDX-License-Identifier: GPL-3.0-or-later

"""Transfer-function presets: small Python files that set the transfer function and material of
`bpy.context.volume.pcvr`, as Blender's preset menus run them (script.execute_preset).

The shipped ones are in the add-on's presets/transfer_function/ (beside ui/): 3D Slicer's volume-rendering
presets, their numbers as Slicer publishes them, and a cloud preset of our own. Users save their own with the Add
Preset button (operators.PCVR_OT_transfer_function_preset_add), into Blender's user presets folder
(scripts/presets/pcvr/transfer_function). Where a user's preset has a shipped one's name, the user's wins.
"""

import os
import re

import bpy

from ..scene.transfer_function import DEFAULT_GRADIENT_RAMP, DEFAULT_RAMP, ramp_elements
from ..scene.typed import as_typed

SUBDIR = os.path.join("pcvr", "transfer_function")
SHIPPED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "presets", "transfer_function")


def search_paths():
    """The folders that hold presets: the shipped one first, then the user's."""
    return [SHIPPED] + bpy.utils.preset_paths(SUBDIR)


def display_name(filename):
    """"CT_Bone.py" -> "CT Bone", as Blender's preset menu shows it."""
    return bpy.path.display_name(filename, title_case=False)


def _key(name):
    """Names compare without case, and with '-', '_' and ' ' alike ("CT-Bone", "ct_bone", "CT Bone")."""
    return re.sub(r"[-_ ]+", " ", name.strip()).lower()


def files():
    """{display name: path} of every preset."""
    found = {}
    for directory in search_paths():
        if not os.path.isdir(directory):
            continue
        for entry in sorted(os.listdir(directory)):
            if entry.endswith(".py"):
                found[display_name(entry)] = os.path.join(directory, entry)
    return found


def find(name):
    """The path of the preset called `name`. KeyError lists the presets there are."""
    available = files()
    by_key = {_key(display): path for display, path in available.items()}
    try:
        return by_key[_key(name)]
    except KeyError:
        raise KeyError(f"no transfer-function preset '{name}'; there are: {', '.join(available)}") from None


def apply(volume, name):
    """Run the preset called `name` on the Volume datablock `volume`."""
    path = find(name)
    with bpy.context.temp_override(volume=volume):
        bpy.utils.execfile(path)


def _elements(ramp, default=DEFAULT_RAMP):
    """A ramp's elements as the lines of a Python list."""
    return "".join(f"        ({as_typed(position)!r}, {tuple(as_typed(c) for c in rgba)!r}),\n"
                   for position, rgba in ramp_elements(ramp, default))


def write(settings, filepath):
    """Save the transfer function, gradient opacity and material of `settings` (a volume's PCVR settings) as a
    preset file."""
    ramp, gradient_ramp = settings.ramp, settings.gradient_ramp
    elements = _elements(ramp)
    interpolation = ramp.interpolation if ramp else 'LINEAR'
    color_mode = ramp.color_mode if ramp else 'RGB'
    with open(filepath, "w", encoding="utf-8") as file:
        file.write(
            "import bpy\n"
            "settings = bpy.context.volume.pcvr\n"
            "settings.set_transfer_function(\n"
            f"    tf_min={as_typed(settings.tf_min)!r}, tf_max={as_typed(settings.tf_max)!r},\n"
            "    elements=[\n"
            f"{elements}"
            "    ],\n"
            f"    interpolation={interpolation!r}, color_mode={color_mode!r},\n"
            ")\n"
            f"settings.use_grid_range = {settings.use_grid_range!r}\n"
            f"settings.use_shading = {settings.use_shading!r}\n"
            f"settings.opacity_scale = {as_typed(settings.opacity_scale)!r}\n"
            "settings.set_gradient_opacity(\n"
            f"    gradient_max={as_typed(settings.gradient_max)!r},\n"
            "    elements=[\n"
            f"{_elements(gradient_ramp, DEFAULT_GRADIENT_RAMP)}"
            "    ],\n"
            f"    interpolation={(gradient_ramp.interpolation if gradient_ramp else 'LINEAR')!r},\n"
            ")\n"
            f"settings.use_gradient_opacity = {settings.use_gradient_opacity!r}\n"
            f"settings.set_material(ambient={as_typed(settings.ambient)!r}, diffuse={as_typed(settings.diffuse)!r}, "
            f"specular={as_typed(settings.specular)!r}, shininess={as_typed(settings.shininess)!r})\n")
