# 3D Slicer's volume-rendering preset "MR-T2-Brain", its numbers as published in Slicer's
# Modules/Loadable/VolumeRendering/Resources/presets.xml (scalarOpacity, colorTransfer, gradientOpacity, shading).
import bpy

bpy.context.volume.pcvr.apply_slicer_preset(
    scalar_opacity=[10,
        0, 0,
        36.05, 0,
        218.302, 0.171429,
        412.406, 1,
        641, 1],
    color_transfer=[16,
        0, 0, 0, 0,
        98.7223, 0.956863, 0.839216, 0.192157,
        412.406, 0, 0.592157, 0.807843,
        641, 1, 1, 1],
    gradient_opacity=[4, 0, 1, 160.25, 1],
    shade=True, ambient=0.3, diffuse=0.6, specular=0.5, specular_power=40,
)
