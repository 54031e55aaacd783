# 3D Slicer's volume-rendering preset "CT-Cardiac", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[12,
        -3024, 0,
        -77.6875, 0,
        94.9518, 0.285714,
        179.052, 0.553571,
        260.439, 0.848214,
        3071, 0.875],
    color_transfer=[24,
        -3024, 0, 0, 0,
        -77.6875, 0.54902, 0.25098, 0.14902,
        94.9518, 0.882353, 0.603922, 0.290196,
        179.052, 1, 0.937033, 0.954531,
        260.439, 0.615686, 0, 0,
        3071, 0.827451, 0.658824, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10,
)
