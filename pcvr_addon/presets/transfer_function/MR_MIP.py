# 3D Slicer's volume-rendering preset "MR-MIP", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[8,
        0, 0,
        98.3725, 0,
        416.637, 1,
        2800, 1],
    color_transfer=[16,
        0, 1, 1, 1,
        98.3725, 1, 1, 1,
        416.637, 1, 1, 1,
        2800, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=False, ambient=0.2, diffuse=1, specular=0, specular_power=1,
)
