# 3D Slicer's volume-rendering preset "CT-Muscle", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[10,
        -3024, 0,
        -155.407, 0,
        217.641, 0.676471,
        419.736, 0.833333,
        3071, 0.803922],
    color_transfer=[20,
        -3024, 0, 0, 0,
        -155.407, 0.54902, 0.25098, 0.14902,
        217.641, 0.882353, 0.603922, 0.290196,
        419.736, 1, 0.937033, 0.954531,
        3071, 0.827451, 0.658824, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10,
)
