# 3D Slicer's volume-rendering preset "CT-MIP", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[8,
        -3024, 0,
        -637.62, 0,
        700, 1,
        3071, 1],
    color_transfer=[16,
        -3024, 0, 0, 0,
        -637.62, 1, 1, 1,
        700, 1, 1, 1,
        3071, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10,
)
