# 3D Slicer's volume-rendering preset "CT-Bone", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[8,
        -3024, 0,
        -16.4458, 0,
        641.385, 0.715686,
        3071, 0.705882],
    color_transfer=[16,
        -3024, 0, 0, 0,
        -16.4458, 0.729412, 0.254902, 0.301961,
        641.385, 0.905882, 0.815686, 0.552941,
        3071, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 255, 1],
    shade=True, ambient=0.1, diffuse=0.9, specular=0.2, specular_power=10,
)
