"""The house rules of issues 19 and 38, read from the sources: each folder of native/src includes only its own layer
and the layers before it, the sub-folders of a layer (shaded/'s) only their own and those before them, include/pcvr
includes nothing private, and the add-on's packages import only their own row and those below, with no circle
between modules."""

import ast
import functools
import re
from pathlib import Path

NATIVE = Path(__file__).resolve().parents[2] / "native"
# Bottom to top, as native/CMakeLists.txt lists them; xray and shaded stand side by side.
LAYERS = ("core", "volume", "view", "splat", "xray", "shaded")
SIDE_BY_SIDE = {"xray", "shaded"}
# A layer's sub-folders, first to last as native/CMakeLists.txt lists them: each includes only its own sub-folder,
# those before it and the layers below; the layer's own folder (shaded/shaded.cpp, the entry points) comes last.
PARTS = {"shaded": ("classify", "light", "sheets", "reference")}
INCLUDE = re.compile(r'^#include "([^"]+)"', re.M)


def sources():
    """Every file under native/src, sub-folders included."""
    return sorted(path for path in NATIVE.glob("src/**/*") if path.is_file())


def place(source):
    """A source's layer and sub-folder (None: the layer's own folder), from its path below src/."""
    parts = Path(source).parts
    return parts[0], parts[1] if len(parts) > 2 else None


@functools.lru_cache(maxsize=None)
def public_place(header):
    """The layer and sub-folder of a public header: where its implementation lives (pcvr/grid.h: volume/grid.cpp),
    or where the headers that include it live for header-only ones."""
    stem = Path(header).stem
    implementations = sorted(NATIVE.glob(f"src/**/{stem}.cpp"))
    if implementations:
        return place(implementations[0].relative_to(NATIVE / "src"))
    users = [place(path.relative_to(NATIVE / "src")) for path in sources() if f'"pcvr/{stem}.h"' in path.read_text()]
    return min(users, key=lambda user: LAYERS.index(user[0])) if users else ("core", None)


def public_layer(header):
    return public_place(header)[0]


def layer_of(include):
    folder = Path(include).parts[0]
    return public_layer(include) if folder == "pcvr" else folder


def part_rank(layer, part):
    """Where a sub-folder stands in its layer's order; the layer's own folder after them all."""
    order = PARTS.get(layer, ())
    return order.index(part) if part is not None else len(order)


def upward_part_includes(files):
    """Includes from one sub-folder of a layer into a later one (or into the layer's own folder), for `files`:
    (path below src/, text) pairs. A public header counts where its implementation lives; one implemented in the
    layer's own folder (pcvr/shaded.h: ShadedParams, ShadedVolume and the entry points) is the layer's vocabulary,
    which every sub-folder speaks, and orders nothing."""
    upward = []
    for source, text in files:
        layer, part = place(source)
        for include in INCLUDE.findall(text):
            if Path(include).parts[0] == "pcvr":
                included_layer, included_part = public_place(include)
                if included_part is None:
                    continue
            else:
                included_layer, included_part = place(include)
            if included_layer == layer and part_rank(layer, included_part) > part_rank(layer, part):
                upward.append(f"{source} ({part or layer}) -> {include} ({included_part or included_layer})")
    return upward


def test_no_include_runs_upwards():
    upward = []
    for path in sources() + sorted(NATIVE.glob("include/pcvr/*.h")):
        in_src = NATIVE / "src" in path.parents
        own = place(path.relative_to(NATIVE / "src"))[0] if in_src else public_layer(path.name)
        for include in INCLUDE.findall(path.read_text()):
            layer = layer_of(include)
            assert layer in LAYERS, f"{path.relative_to(NATIVE)} includes {include}, in no layer"
            above = LAYERS.index(layer) > LAYERS.index(own)
            sideways = {layer, own} == SIDE_BY_SIDE
            if above or sideways:
                upward.append(f"{path.relative_to(NATIVE)} ({own}) -> {include} ({layer})")
    assert not upward, "includes that run upwards:\n" + "\n".join(upward)


def test_no_include_runs_up_a_layers_sub_folders():
    files = [(str(path.relative_to(NATIVE / "src")), path.read_text()) for path in sources()]
    upward = upward_part_includes(files)
    assert not upward, "includes that run up a layer's sub-folders:\n" + "\n".join(upward)


def test_sub_folder_check_flags_a_later_sub_folder():
    """The check above can fail: classify including sheets, sheets including the entry points' folder, and light
    reaching the ray caster through a public header implemented there would all be upwards."""
    files = [("shaded/classify/emission.h", '#include "shaded/sheets/sheet_walk.h"\n'),
             ("shaded/sheets/sheet_walk.h", '#include "shaded/entry.h"\n#include "shaded/classify/emission.h"\n'),
             ("shaded/light/light_volume.h", '#include "pcvr/shading.h"\n#include "pcvr/transfer_function.h"\n')]
    assert len(upward_part_includes(files)) == 2
    assert public_place("pcvr/shading.h") == ("shaded", "light")
    assert public_place("pcvr/transfer_function.h") == ("shaded", "classify")


def test_public_headers_include_only_public_headers():
    private = [f"{path.name} -> {include}" for path in NATIVE.glob("include/pcvr/*.h")
               for include in INCLUDE.findall(path.read_text()) if not include.startswith("pcvr/")]
    assert not private, private


def test_every_source_sits_in_a_layer():
    stray = [path.name for path in NATIVE.glob("src/*") if path.is_file()]
    folders = {path.name for path in NATIVE.glob("src/*") if path.is_dir()}
    assert not stray and folders == set(LAYERS), (stray, folders)
    for layer in LAYERS:
        parts = {path.name for path in (NATIVE / "src" / layer).iterdir() if path.is_dir()}
        assert parts == set(PARTS.get(layer, ())), (layer, parts)
        for part in parts:
            nested = [path.name for path in (NATIVE / "src" / layer / part).iterdir() if path.is_dir()]
            assert not nested, (layer, part, nested)


# The add-on's packages bottom to top (issue 38): each module imports, at module level, only from its own row and
# the rows below. The command line and its batches share a row (a batch renders what the command line sets up, and
# the command line runs batches); the root package (registration), engine.py and __main__.py sit on top.
ADDON_LAYERS = (("compat", "volume_import"), ("scene",), ("render",), ("io",), ("ui",), ("cli", "batch"),
                ("", "engine", "__main__"))


@functools.lru_cache(maxsize=None)
def addon_imports():
    """{module: the add-on modules it imports at module level}, modules by dotted name below pcvr_addon ("" for
    the package itself). Function-level imports are lazy on purpose (the native module, Blender's gpu, the batch's
    Dask) and not counted."""
    addon = NATIVE.parent / "pcvr_addon"
    modules = {}
    for path in addon.rglob("*.py"):
        parts = list(path.relative_to(addon).with_suffix("").parts)
        if parts[0] == "presets":  # Blender's preset scripts: data that the preset menus run, not modules
            continue
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    imports = {}
    for name, path in modules.items():
        package = name.split(".") if path.name == "__init__.py" and name else name.split(".")[:-1]
        found = set()
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.level:
                base = package[:len(package) - node.level + 1]
                stem = base + (node.module.split(".") if node.module else [])
                # `from . import x` runs the package first, as every import of a submodule does: not an edge.
                named = [".".join(stem)] if node.module else []
                for candidate in named + [".".join(stem + [alias.name]) for alias in node.names]:
                    if candidate in modules and candidate != name:
                        found.add(candidate)
        imports[name] = frozenset(found)
    return imports


def addon_rank(module):
    """The row of ADDON_LAYERS that holds the module's package (its first name)."""
    package = module.split(".")[0]
    return next(rank for rank, row in enumerate(ADDON_LAYERS) if package in row)


def test_addon_packages_import_only_their_own_row_and_those_below():
    imports = addon_imports()
    unplaced = sorted({module.split(".")[0] for module in imports} - {p for row in ADDON_LAYERS for p in row})
    assert not unplaced, f"packages in no row of ADDON_LAYERS: {unplaced}"
    upward = [f"{module} -> {imported}" for module, found in sorted(imports.items()) for imported in sorted(found)
              if addon_rank(imported) > addon_rank(module)]
    assert not upward, "add-on imports that run upwards:\n" + "\n".join(upward)
    assert addon_rank("scene.volumes") < addon_rank("render.passes") < addon_rank("ui.panels")


def test_addon_modules_import_no_circle():
    """No module of the add-on imports, at module level, one that imports it back."""
    imports = addon_imports()

    def circle_through(start):
        stack = [(start, [start])]
        while stack:
            module, path = stack.pop()
            for imported in imports[module]:
                if imported == start:
                    return path + [start]
                if imported not in path:
                    stack.append((imported, path + [imported]))
        return None

    circles = [" -> ".join(circle) for circle in map(circle_through, sorted(imports)) if circle]
    assert len(imports) > 30 and not circles, circles
