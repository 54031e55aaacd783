# Clouds and smoke (PCVR's own; 3D Slicer has none): densities 0 to 1 as simulations and cloud VDBs have them,
# white, transparent at density 0 and growing more opaque with density, lit mostly by the sun with a good
# share of sky (the world colour) and no highlights.
import bpy

settings = bpy.context.volume.pcvr
settings.set_transfer_function(
    tf_min=0.0, tf_max=1.0,
    elements=[
        (0.0, (0.8, 0.8, 0.8, 0.0)),
        (1.0, (1.0, 1.0, 1.0, 0.3)),
    ],
)
settings.opacity_scale = 1.0
settings.use_gradient_opacity = False
settings.set_material(ambient=0.4, diffuse=0.8, specular=0.0, shininess=1.0)
settings.use_shading = True
