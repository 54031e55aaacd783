# 3D Slicer's volume-rendering preset "CT-AAA", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[12,
        -3024, 0,
        143.556, 0,
        166.222, 0.686275,
        214.389, 0.696078,
        419.736, 0.833333,
        3071, 0.803922],
    color_transfer=[24,
        -3024, 0, 0, 0,
        143.556, 0.615686, 0.356863, 0.184314,
        166.222, 0.882353, 0.603922, 0.290196,
        214.389, 1, 1, 1,
        419.736, 1, 0.937033, 0.954531,
        3071, 0.827451, 0.658824, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10,
)
