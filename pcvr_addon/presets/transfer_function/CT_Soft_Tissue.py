# 3D Slicer's volume-rendering preset "CT-Soft-Tissue", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[10,
        -2048, 0,
        -167.01, 0,
        -160, 1,
        240, 1,
        3661, 1],
    color_transfer=[20,
        -2048, 0, 0, 0,
        -167.01, 0, 0, 0,
        -160, 0.0556356, 0.0556356, 0.0556356,
        240, 1, 1, 1,
        3661, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=False, ambient=0.2, diffuse=1, specular=0, specular_power=1,
)
