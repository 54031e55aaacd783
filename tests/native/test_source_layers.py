"""The house rules of issue 19, read from the sources: each folder of native/src includes only its own layer and
the layers before it, include/pcvr includes nothing private, and the add-on's modules import no circle."""

import ast
import functools
import re
from pathlib import Path

NATIVE = Path(__file__).resolve().parents[2] / "native"
# Bottom to top, as native/CMakeLists.txt lists them; xray and shaded stand side by side.
LAYERS = ("core", "volume", "view", "splat", "xray", "shaded")
SIDE_BY_SIDE = {"xray", "shaded"}
INCLUDE = re.compile(r'^#include "([^"]+)"', re.M)


@functools.lru_cache(maxsize=None)
def public_layer(header):
    """The layer of a public header: where its implementation lives (pcvr/grid.h: volume/grid.cpp), or where
    the headers that include it live for header-only ones."""
    stem = Path(header).stem
    sources = sorted(NATIVE.glob(f"src/*/{stem}.cpp"))
    if sources:
        return sources[0].parent.name
    users = [path.parent.name for path in NATIVE.glob("src/*/*") if f'"pcvr/{stem}.h"' in path.read_text()]
    return min(users, key=LAYERS.index) if users else "core"


def layer_of(include):
    folder = Path(include).parts[0]
    return public_layer(include) if folder == "pcvr" else folder


def test_no_include_runs_upwards():
    upward = []
    for path in sorted(NATIVE.glob("src/*/*")) + sorted(NATIVE.glob("include/pcvr/*.h")):
        own = path.parent.name if path.parent.parent.name == "src" else public_layer(path.name)
        for include in INCLUDE.findall(path.read_text()):
            layer = layer_of(include)
            assert layer in LAYERS, f"{path.relative_to(NATIVE)} includes {include}, in no layer"
            above = LAYERS.index(layer) > LAYERS.index(own)
            sideways = {layer, own} == SIDE_BY_SIDE
            if above or sideways:
                upward.append(f"{path.relative_to(NATIVE)} ({own}) -> {include} ({layer})")
    assert not upward, "includes that run upwards:\n" + "\n".join(upward)


def test_public_headers_include_only_public_headers():
    private = [f"{path.name} -> {include}" for path in NATIVE.glob("include/pcvr/*.h")
               for include in INCLUDE.findall(path.read_text()) if not include.startswith("pcvr/")]
    assert not private, private


def test_every_source_sits_in_a_layer():
    stray = [path.name for path in NATIVE.glob("src/*") if path.is_file()]
    folders = {path.name for path in NATIVE.glob("src/*") if path.is_dir()}
    assert not stray and folders == set(LAYERS), (stray, folders)


def test_addon_modules_import_no_circle():
    """No module of the add-on imports, at module level, one that imports it back (function-level imports are
    lazy on purpose: the native module, Blender's gpu, the batch's Dask)."""
    addon = NATIVE.parent / "pcvr_addon"
    modules = {}
    for path in addon.rglob("*.py"):
        parts = list(path.relative_to(addon).with_suffix("").parts)
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
        imports[name] = found

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

    circles = [" -> ".join(circle) for circle in map(circle_through, sorted(modules)) if circle]
    assert len(modules) > 30 and not circles, circles
