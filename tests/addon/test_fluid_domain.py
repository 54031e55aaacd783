"""Fluid gas domains (Quick Smoke, Quick Fire) render from their OpenVDB cache frame as Cycles shows them
(pcvr_addon/scene/fluid_domain.py, issue 41 item 3).

The bundled Mantaflow cannot bake here: in the pip bpy (5.0.1) its Python side is broken ('LevelsetGrid' object has
no attribute 'setConst', then NameErrors for every step function), `bpy.ops.fluid.bake_all()` aborts the interpreter
(SIGABRT: "Manta::Error: can't clean grid cache, some grids are still in use") before writing any file, and so does
leaving a domain alive at exit (`drop_domains` below removes them). So these tests write the cache frames
themselves, in Blender's layout: `data/fluid_data_NNNN.vdb` with Mantaflow's grid names (`density`, `flame`, its
heat as `temperature`, `velocity`), each under Mantaflow's transform (a bare scale: the longest domain side over
the most cells, no position) and its per-grid metadata (`file_base_resolution`, `file_voxel_size`; as strings,
which is what pn.write_vdb writes: PCVR reads neither), `noise/fluid_noise_NNNN.vdb` (`density_noise`,
`flame_noise`) and `config/config_NNNN.uni` as MANTA::writeConfiguration packs it. The domains are made by
bpy.ops.object.quick_smoke as the menu does (style 'SMOKE', or 'FIRE' for Quick Fire), with Bake All's cache type
('ALL': a Replay cache at its first frame, flagged outdated by our edits, is deleted by Blender).

Blender cannot evaluate an adaptive domain here either (reallocating the solver for the config's resolution aborts
the same way), so the adaptive placement is checked on the domain's settings without a render.
"""

import gzip
import math
import struct
from pathlib import Path

import bpy
import numpy as np
import pytest

import blender_scenes as bs
import lit_scenes as ls
import material_scenes as ms
from _io_helpers import describe, file_grids, run_python
from pcvr_addon.scene import fluid_domain, volumes

ADDON_TESTS = Path(__file__).resolve().parent

SIZE = 48
# Domain and plain volume carry the same grids at the same places (the temperature mapped from the flame per voxel,
# as Cycles does): measured bit-identical in X-ray, 7e-8 of the image's maximum shaded.
XRAY_TOLERANCE = 1e-6
SHADED_TOLERANCE = 1e-6


def in_blender(tmp_path, scenario, **arguments):
    """Run `scenario(tmp_path, **arguments)` of this module in a fresh Blender, a subprocess that leaves with
    os._exit: freeing a domain's solver (removing it, or at exit) aborts this Mantaflow (module docstring).
    Returns what the scenario returned ({name: array or list of str})."""
    code = f"""
        import os, pathlib, sys
        os.chdir({str(tmp_path)!r})  # Mantaflow writes its noise tile (waveletNoiseTile.bin, 24 MB) where it runs
        sys.path[:0] = {[str(ADDON_TESTS.parent.parent), str(ADDON_TESTS.parent), str(ADDON_TESTS)]!r}
        import bpy, numpy as np, pcvr_addon
        bpy.ops.wm.read_factory_settings(use_empty=True)
        pcvr_addon.register()
        import test_fluid_domain as t
        result = t.{scenario}(pathlib.Path({str(tmp_path)!r}), **{arguments!r})
        np.savez({str(tmp_path / "result.npz")!r}, **{{k: np.asarray(v) for k, v in result.items()}})
        sys.stdout.flush()
        os._exit(0)
    """
    proc = run_python(code)
    assert proc.returncode == 0, describe(proc)
    with np.load(tmp_path / "result.npz") as result:
        return {name: result[name] for name in result.files}


def fluid_modifier(obj):
    """The object's Fluid modifier, by type: Quick Smoke names it "Fluid" in Blender 4.2 and 5, "FLUID" in 4.5."""
    return next(modifier for modifier in obj.modifiers if modifier.type == 'FLUID')


def quick_domain(directory, style='SMOKE'):
    """A flow cube and the domain quick_smoke makes around it, its cache in `directory` (Bake All): the domain."""
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    bpy.ops.object.quick_smoke(style=style)
    domain = bpy.context.active_object
    settings = fluid_modifier(domain).domain_settings
    settings.resolution_max = 16
    settings.cache_type = 'ALL'
    settings.cache_directory = str(directory)
    return domain


def base_resolution(domain):
    """The cells manta_set_domain_from_mesh gives the domain: the longest side resolution_max, the others in
    proportion (rounded, at least 4)."""
    size = np.array(domain.dimensions)
    res_max = fluid_modifier(domain).domain_settings.resolution_max
    return tuple(res_max if s == size.max() else max(int(s * res_max / size.max() + 0.5), 4) for s in size)


def plume(res, seed=3):
    """{Mantaflow grid name: values}: smoke rising through the domain, a flame at its foot, heat everywhere in
    it (2, which read as a temperature would glow at 2000 K)."""
    rng = np.random.default_rng(seed)
    i, j, k = (np.indices(res, dtype=np.float64) + 0.5) / np.array(res)[:, None, None, None]
    r2 = ((i - 0.5) ** 2 + (j - 0.5) ** 2) / (0.08 + 0.2 * k) ** 2
    density = np.exp(-2 * r2) * (0.7 + 0.3 * rng.random(res)) * np.clip(1.1 - k, 0, 1)
    density[density < 0.02] = 0.0
    flame = np.clip(np.exp(-4 * r2 - ((k - 0.25) / 0.12) ** 2) * 1.2, 0, 1) * (density > 0)
    flame[flame < 0.005] = 0.0
    return {"density": (0.4 * density).astype(np.float32), "flame": flame.astype(np.float32),
            "temperature": (2.0 * (density > 0)).astype(np.float32)}


def write_frame(directory, frame, grids, domain, folder="data", name="fluid_data", config=True):
    """Cache frame `frame` of `domain` as Mantaflow writes it: the grids under its transform and metadata, and the
    frame's config (a non-adaptive domain's: all its cells)."""
    res = next(iter(grids.values())).shape
    voxel = max(domain.dimensions) / max(res)  # worldSize * dx: the longest side over the most cells
    path = directory / folder / f"{name}_{frame:04d}.vdb"
    path.parent.mkdir(parents=True, exist_ok=True)
    metadata = {grid: {"file_base_resolution": " ".join(map(str, res)), "file_voxel_size": str(voxel)}
                for grid in grids}
    import pcvr_native as pn
    pn.write_vdb(str(path), file_grids(grids, np.diag([voxel, voxel, voxel, 1.0])), metadata=metadata)
    if config:
        base = base_resolution(domain)
        write_config(directory, frame, base, (-1, -1, -1), (1, 1, 1), base, (0, 0, 0), base, domain.matrix_world)
    return path


def write_config(directory, frame, res, p0, p1, base_res, res_min, res_max, obmat):
    """config/config_NNNN.uni as MANTA::writeConfiguration writes it (float obmat[4][4] column by column)."""
    path = directory / "config" / f"config_{frame:04d}.uni"
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = np.array(obmat, dtype=np.float32).T.ravel()
    with gzip.open(path, "wb") as file:
        file.write(struct.pack("<i3iff3f3f3f3i3f16f3i3i3i3fi4s", 0, *res, 1.0 / max(base_res), 0.1, *p0, *p1, *p0,
                               0, 0, 0, 0.0, 0.0, 0.0, *columns, *base_res, *res_min, *res_max, 0.0, 0.0, 0.0, 0,
                               b"C01\0"))


def cells_volume(path, grids, domain, name="Cells"):
    """A plain volume object holding `grids` where Cycles puts the domain's cells: one value per cell centre over
    the domain cube's [-1, 1]^3, under the domain's transform."""
    res = np.array(next(iter(grids.values())).shape)
    index_to_object = np.diag([*(2.0 / res), 1.0])
    index_to_object[:3, 3] = -1.0 + 1.0 / res
    import pcvr_native as pn
    pn.write_vdb(str(path), file_grids(grids, index_to_object))
    obj = bs.add_volume(name, path)
    obj.matrix_world = domain.matrix_world
    # A domain is a mesh, whose material Cycles reads per world unit (a mesh has no Render > Space): so is this.
    obj.data.render.space = 'WORLD'
    return obj


def side_camera():
    bs.add_camera(location=(0.0, -10.0, 1.0), rotation=(math.pi / 2, 0.0, 0.0), ortho_scale=5.5)


def render_each(scene, objects, mode):
    """{object name: its render with the others hidden}."""
    scene.pcvr.mode = mode
    images = {}
    for shown in objects:
        for obj in objects:
            obj.hide_render = obj is not shown
        passes = bs.render(scene)
        images[shown.name] = bs.xray(passes) if mode == 'XRAY' else ls.combined(passes)
    return images


def smoke_scenario(tmp_path):
    scene = bs.setup(SIZE, SIZE)
    side_camera()
    domain = quick_domain(tmp_path / "cache")
    grids = plume(base_resolution(domain))
    write_frame(tmp_path / "cache", 1, grids, domain)
    cells = cells_volume(tmp_path / "cells.vdb", {"density": grids["density"]}, domain)
    images = render_each(scene, [domain, cells], 'XRAY')
    return {"smoke": images[domain.name], "reference": images[cells.name],
            "resolution": fluid_modifier(domain.evaluated_get(bpy.context.evaluated_depsgraph_get()))
            .domain_settings.domain_resolution[:], "expected_resolution": base_resolution(domain)}


def test_quick_smoke_renders_its_cache_frame_where_blender_puts_the_cells(tmp_path):
    """X-ray: the domain's density where the smoke is, the same image as the grid placed by hand on the cells."""
    result = in_blender(tmp_path, "smoke_scenario")
    smoke, reference = result["smoke"], result["reference"]
    assert tuple(result["resolution"]) == tuple(result["expected_resolution"]) == (10, 10, 16)
    assert smoke.max() > 0.05, "the domain renders nothing"
    rows, columns = np.nonzero(smoke > 1e-3 * smoke.max())
    # The smoke rises through the middle of the domain, densest at its foot (z -1.5..3.5 seen from the front).
    assert abs(columns.mean() - (SIZE - 1) / 2) < 1
    assert np.argmax(smoke.max(axis=1)) > SIZE / 2
    bs.assert_matches(smoke, reference, XRAY_TOLERANCE)


def fire_scenario(tmp_path):
    scene = ls.shaded_setup(SIZE, SIZE)
    side_camera()
    ls.add_light('SUN', rotation=(0.6, 0.2, 0.0), power=math.pi)
    domain = quick_domain(tmp_path / "cache", style='FIRE')
    grids = plume(base_resolution(domain))
    write_frame(tmp_path / "cache", 1, grids, domain)
    flame = grids["flame"]
    temperature = np.where(flame > 0.01, 1.5 + 1.5 * flame, 0.0).astype(np.float32)
    cells = cells_volume(tmp_path / "cells.vdb", {"density": grids["density"], "temperature": temperature}, domain)
    ms.use_material(cells, domain.active_material)
    warnings = ms.prepared().warnings
    images = render_each(scene, [domain, cells], 'SHADED')
    return {"fire": images[domain.name], "reference": images[cells.name], "warnings": list(warnings)}


def test_quick_fire_shades_as_cycles_reads_its_grids(tmp_path):
    """Shaded with Quick Fire's material: smoke of Density 5 and blackbody flames from the temperature Cycles
    derives from the flame grid (1000 K x (1.5 + 1.5 flame)), not from the file's `temperature` (heat)."""
    result = in_blender(tmp_path, "fire_scenario")
    fire, reference = result["fire"], result["reference"]
    assert result["warnings"].size == 0
    assert fire[..., 3].max() > 0.2 and fire[..., 0].max() > 2 * fire[..., 2].max(), "no flames"
    np.testing.assert_allclose(fire, reference, atol=SHADED_TOLERANCE * reference.max())


def noise_scenario(tmp_path):
    scene = bs.setup(SIZE, SIZE)
    side_camera()
    domain = quick_domain(tmp_path / "cache")
    settings = fluid_modifier(domain).domain_settings
    settings.use_noise, settings.noise_scale = True, 2
    res = base_resolution(domain)
    fine = plume(tuple(2 * r for r in res), seed=5)
    write_frame(tmp_path / "cache", 1, plume(res), domain)
    write_frame(tmp_path / "cache", 1, {"density_noise": fine["density"]}, domain, folder="noise", name="fluid_noise",
                config=False)
    cells = cells_volume(tmp_path / "cells.vdb", {"density": fine["density"]}, domain)
    images = render_each(scene, [domain, cells], 'XRAY')
    return {"smoke": images[domain.name], "reference": images[cells.name]}


def test_noise_renders_the_upres_grid(tmp_path):
    """With Noise, density is the noise cache's density_noise at Noise's upres factor (X-ray)."""
    result = in_blender(tmp_path, "noise_scenario")
    bs.assert_matches(result["smoke"], result["reference"], XRAY_TOLERANCE)


def warnings_scenario(tmp_path, hidden=False, frame_end=250, frame_offset=0, frame=1):
    """The warnings and volumes a render of a Quick Smoke domain reads, its cache empty, and how many times its cache
    was looked for."""
    bs.setup(SIZE, SIZE)
    domain = quick_domain(tmp_path / "cache")
    settings = fluid_modifier(domain).domain_settings
    settings.cache_frame_end, settings.cache_frame_offset = frame_end, frame_offset
    domain.hide_render = hidden
    looked_at = []
    read_frame = fluid_domain.read_frame
    fluid_domain.read_frame = lambda *args: looked_at.append(args) or read_frame(*args)
    bpy.context.scene.frame_set(frame)
    prepared = ms.prepared()
    return {"warnings": list(prepared.warnings), "errors": list(prepared.errors), "volumes": len(prepared.volumes),
            "looked_at": len(looked_at)}


def test_a_missing_cache_frame_warns_naming_the_domain_and_folder(tmp_path):
    result = in_blender(tmp_path, "warnings_scenario")
    folder = str(tmp_path / "cache" / "data")
    assert result["volumes"] == 0 and result["errors"].size == 0
    assert any("Fluid domain 'Smoke Domain'" in w and "frame 1" in w and folder in w for w in result["warnings"])


def test_hidden_domains_cost_nothing(tmp_path):
    result = in_blender(tmp_path, "warnings_scenario", hidden=True)
    assert result["looked_at"] == 0 and result["warnings"].size == 0


def test_frames_outside_the_cache_show_nothing_and_offsets_shift_them(tmp_path):
    """Outside the cache's frames Cycles renders nothing, and so does PCVR, without a warning; a Bake All cache
    with a frame offset shows cache frame N at scene frame N + offset."""
    outside = in_blender(tmp_path, "warnings_scenario", frame_end=3, frame=4)
    assert outside["looked_at"] == 1 and outside["volumes"] == 0 and outside["warnings"].size == 0
    shifted = in_blender(tmp_path, "warnings_scenario", frame_offset=3, frame=4)
    assert any("no cache for frame 1 " in w for w in shifted["warnings"])
    cases = [('REPLAY', 0, 5, 5), ('REPLAY', 0, 251, None), ('ALL', 10, 15, 5), ('MODULAR', -2, 0, 2),
             ('ALL', -2, 251, None)]
    for cache_type, offset, frame, expected in cases:
        settings = type("Settings", (), dict(cache_type=cache_type, cache_frame_offset=offset, cache_frame_start=1,
                                             cache_frame_end=250))
        assert fluid_domain.cache_frame(settings, frame) == expected, (cache_type, offset, frame)


def uni_scenario(tmp_path):
    domain = quick_domain(tmp_path / "cache")
    modifier = fluid_modifier(domain)
    modifier.domain_settings.cache_data_format = 'UNI'
    # Read from the settings, not rendered: Blender aborts evaluating this domain with a Uni cache here.
    return {"message": fluid_domain.read_frame(domain, modifier, np.array(domain.matrix_world), 1).message}


def test_a_uni_cache_is_named_not_read(tmp_path):
    message = str(in_blender(tmp_path, "uni_scenario")["message"])
    assert "UNI format" in message and "OpenVDB" in message


def adaptive_scenario(tmp_path):
    """An adaptive domain's cache frame 1 (cells res_min..res_max of its base resolution), the domain moved by 0.75
    along x since: what read_frame makes of it, read from the settings (module docstring)."""
    domain = quick_domain(tmp_path / "cache")
    modifier = fluid_modifier(domain)
    modifier.domain_settings.use_adaptive_domain = True
    base = base_resolution(domain)
    res = tuple(b - a for a, b in zip(ADAPTIVE_MIN, ADAPTIVE_MAX))
    baked_at = np.array(domain.matrix_world)
    write_frame(tmp_path / "cache", 1, {"density": np.ones(res, np.float32)}, domain, config=False)
    write_config(tmp_path / "cache", 1, res, (-1, -1, -1), (1, 1, 1), base, ADAPTIVE_MIN, ADAPTIVE_MAX, baked_at)
    moved = baked_at.copy()
    moved[0, 3] += 0.75
    frame = fluid_domain.read_frame(domain, modifier, moved, 1)
    without_config = fluid_domain.read_frame(domain, modifier, moved, 2)
    return {"message": frame.message, "box": frame.box, "index_to_object": frame.grids["density"].index_to_object,
            "baked_at": baked_at, "moved": moved, "base": base, "scale": domain.scale[:],
            "without_config": without_config.message}


ADAPTIVE_MIN, ADAPTIVE_MAX = (2, 3, 1), (8, 7, 12)


def test_an_adaptive_domain_places_the_cells_of_its_cache_frame(tmp_path):
    """The adaptive box from the frame's config: p0 + cell size x res_min .. res_max, kept where the domain was when
    baked (create_smoke_geometry's shift)."""
    result = in_blender(tmp_path, "adaptive_scenario")
    assert str(result["message"]) == ""
    cell = 2.0 / result["base"]
    shift = np.array([-0.75 / result["scale"][0], 0.0, 0.0])
    low, high = -1 + cell * np.array(ADAPTIVE_MIN) + shift, -1 + cell * np.array(ADAPTIVE_MAX) + shift
    np.testing.assert_allclose(result["box"], [low, high], atol=1e-6)
    # The first cell's centre, in world space, is where it was at bake time.
    first = result["moved"] @ result["index_to_object"] @ [0, 0, 0, 1]
    np.testing.assert_allclose(first[:3], (result["baked_at"] @ [*(low - shift + cell / 2), 1])[:3], atol=1e-6)
    assert "no cache for frame 2" in str(result["without_config"])


def test_a_medium_naming_no_grid_reads_a_noise_domains_density():
    """With Noise, a domain's grid is the file's 'density_noise'; a medium that names no attribute (a Volume Scatter
    without one) still reads the domain's density attribute, not a grid of that file name."""
    from pcvr_addon.scene.volume_material import GridMedium

    noise = fluid_domain.DomainGrid("fluid_noise_0001.vdb", "density_noise", tuple(map(tuple, np.eye(4))))
    domain = volumes.DomainSource(name="Smoke Domain", volume=None, filepath=noise.filepath, grid_name=noise.grid,
                                  object_to_world=np.eye(4), density_scale=1.0, error="",
                                  grid_names=frozenset({"density"}), grids={"density": noise})
    medium = GridMedium(grid=None, extinction=5.0)
    assert domain.attribute(medium) in domain.grid_names
    part, _ = domain.part(medium)
    assert (part.filepath, part.grid_name) == (noise.filepath, "density_noise")
    plain = volumes.VolumeSource(name="Smoke", volume=None, filepath="smoke.vdb", grid_name="smoke",
                                 object_to_world=np.eye(4), density_scale=1.0, error="")
    assert plain.attribute(medium) == "smoke" and plain.attribute(GridMedium(grid="flame")) == "flame"
