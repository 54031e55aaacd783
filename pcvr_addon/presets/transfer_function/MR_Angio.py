# 3D Slicer's volume-rendering preset "MR-Angio", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[12,
        -2048, 0,
        151.354, 0,
        158.279, 0.4375,
        190.112, 0.580357,
        200.873, 0.732143,
        3661, 0.741071],
    color_transfer=[24,
        -2048, 0, 0, 0,
        151.354, 0, 0, 0,
        158.279, 0.74902, 0.376471, 0,
        190.112, 1, 0.866667, 0.733333,
        200.873, 0.937255, 0.937255, 0.937255,
        3661, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.2, diffuse=1, specular=0, specular_power=1,
)
