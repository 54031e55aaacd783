# 3D Slicer's volume-rendering preset "MR-Default", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[12,
        0, 0,
        20, 0,
        40, 0.15,
        120, 0.3,
        220, 0.375,
        1024, 0.5],
    color_transfer=[24,
        0, 0, 0, 0,
        20, 0.168627, 0, 0,
        40, 0.403922, 0.145098, 0.0784314,
        120, 0.780392, 0.607843, 0.380392,
        220, 0.847059, 0.835294, 0.788235,
        1024, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.2, diffuse=1, specular=0, specular_power=1,
)
