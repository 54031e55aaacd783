# 3D Slicer's volume-rendering preset "CT-Lung", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[12,
        -1000, 0,
        -600, 0,
        -599, 0.15,
        -400, 0.15,
        -399, 0,
        2952, 0],
    color_transfer=[24,
        -1000, 0.3, 0.3, 1,
        -600, 0, 0, 1,
        -530, 0.134704, 0.781726, 0.0724558,
        -460, 0.929244, 1, 0.109473,
        -400, 0.888889, 0.254949, 0.0240258,
        2952, 1, 0.3, 0.3],
    gradient_opacity=[6, 0, 1, 985.12, 1, 988, 1],
    shade=True, ambient=0.2, diffuse=1, specular=0, specular_power=1,
)
