"""The layer rule, read from the source (ast, every import including those inside functions):

    blender → render → techniques → structures → gpu → core        (each may import the layers to its right)
    measure → {blender, render, core}
    ui, operators → {blender, render, core, measure}
    cli → anything; nothing imports cli; no import circles between modules

and bpy (with bmesh, mathutils, gpu_extras) only in blender, measure, ui and operators: the renderer itself
never touches Blender. moderngl only in gpu (everything above reaches GL through it).
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ENGINE_LAYERS = ("core", "gpu", "structures", "techniques", "render", "blender", "measure")
ALLOWED = {
    "core": {"core"},
    "gpu": {"gpu", "core"},
    "structures": {"structures", "gpu", "core"},
    "techniques": {"techniques", "structures", "gpu", "core"},
    "render": {"render", "techniques", "structures", "gpu", "core"},
    "blender": {"blender", "render", "techniques", "structures", "gpu", "core"},
    "measure": {"measure", "blender", "render", "core"},
    "ui": {"ui", "blender", "render", "core", "measure"},
    "operators": {"operators", "blender", "render", "core", "measure"},
}
BLENDER_MODULES = {"bpy", "bmesh", "mathutils", "gpu_extras", "bl_ui"}
BPY_LAYERS = {"blender", "measure", "ui", "operators", "cli"}


def _modules():
    """(dotted module name inside the package, path, is_package) for every source file."""
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        if rel.parts[0] in {".venv", "tests", "tools", "build", "wheels"} or "__pycache__" in rel.parts:
            continue
        parts = list(rel.with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        yield ".".join(parts), path, is_package


def _imports(module: str, path: Path, is_package: bool):
    """Dotted names (relative to the package root, or absolute for outside modules) this file imports."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                name = alias.name
                if name.startswith("penumbra."):
                    yield name[len("penumbra."):], node.lineno
                else:
                    yield "<ext>." + name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                name = node.module or ""
                if name == "penumbra" or name.startswith("penumbra."):
                    base = name[len("penumbra."):] if "." in name else ""
                else:
                    yield "<ext>." + name, node.lineno
                    continue
            else:
                up = package[: len(package) - (node.level - 1)]
                base = ".".join(up + ([node.module] if node.module else []))
            for alias in node.names:
                yield (f"{base}.{alias.name}" if base else alias.name), node.lineno


def _layer(name: str) -> str | None:
    parts = name.split(".")
    if parts[0] == "engine":
        if len(parts) >= 2 and parts[1] in ENGINE_LAYERS:
            return parts[1]
        if len(parts) >= 2 and parts[1] == "cli":
            return "cli"
        return None
    if parts[0] in ("ui", "operators"):
        return parts[0]
    return None


def _all_imports():
    known = {m for m, _, _ in _modules()}
    for module, path, is_package in _modules():
        for name, line in _imports(module, path, is_package):
            # `from .x import y` names either a module x.y or a symbol y of x: keep the module part
            target = name if name.startswith("<ext>") or name in known else name.rsplit(".", 1)[0]
            yield module, path, line, target


def test_every_engine_module_lives_in_a_layer():
    strays = [m for m, _, _ in _modules() if m.startswith("engine.") and _layer(m) is None]
    assert strays == [], f"engine modules outside the layers {ENGINE_LAYERS}: {strays}"


def test_imports_flow_one_way():
    broken = []
    for module, path, line, target in _all_imports():
        src, dst = _layer(module), _layer(target)
        if src is None or dst is None or src == "cli":
            continue
        if dst == "cli":
            broken.append(f"{path.relative_to(ROOT)}:{line} imports the command line ({target})")
        elif dst not in ALLOWED[src]:
            broken.append(f"{path.relative_to(ROOT)}:{line}: {src} may not import {dst} ({target})")
    assert broken == [], "\n".join(broken)


def test_blender_and_gl_stay_in_their_layers():
    broken = []
    for module, path, line, target in _all_imports():
        if not target.startswith("<ext>."):
            continue
        top = target[len("<ext>."):].split(".")[0]
        layer = _layer(module)
        if layer is None:
            continue
        if top in BLENDER_MODULES and layer not in BPY_LAYERS:
            broken.append(f"{path.relative_to(ROOT)}:{line}: {layer} imports {top}")
        if top == "moderngl" and layer != "gpu":
            broken.append(f"{path.relative_to(ROOT)}:{line}: {layer} imports moderngl")
    assert broken == [], "\n".join(broken)


def test_no_import_circles():
    graph: dict[str, set] = {}
    known = {m for m, _, _ in _modules()}
    for module, _, _, target in _all_imports():
        if target in known and target != module:
            graph.setdefault(module, set()).add(target)
    # A package's __init__ importing its own submodules (registries) is not a circle through the package.
    for module in list(graph):
        graph[module] = {t for t in graph[module] if not module.startswith(t + ".")}
    cycles, state = [], {}

    def visit(node, stack):
        state[node] = 1
        stack.append(node)
        for nxt in graph.get(node, ()):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    assert cycles == [], "import circles: " + "; ".join(" → ".join(c) for c in cycles)
