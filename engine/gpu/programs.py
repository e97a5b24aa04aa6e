"""GLSL sources under glsl/, a tiny `#include`, and compile errors that name the file and line.

Each file that takes part in a program gets a source-string number; `#line N K` directives keep the
driver's line numbers true to the file, and the error text is rewritten from `K:N(col)` to `path:N`.
"""
from __future__ import annotations

import re
from pathlib import Path

from ..core.matrices import mat_uniform  # noqa: F401  (re-exported: every program user packs matrices)
from ..core.shader_constants import DEFINES as SHARED_DEFINES, glsl_literal

GLSL_ROOT = Path(__file__).resolve().parents[2] / "glsl"
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$')
_VERSION = "#version 450 core\n"


class ShaderError(RuntimeError):
    """A GLSL file failed to load or compile; the message names the file and line."""


def expand(name: str, defines: dict | None = None) -> tuple[str, list[str]]:
    """Source of glsl/`name` with includes inlined, and the list of files indexed by source-string number.
    Every program gets the shared constants (core/shader_constants.py) as defines, then `defines`."""
    files: list[str] = []
    body = _expand(name, files, set())
    head = (_VERSION + "".join(f"#define {k} {glsl_literal(v)}\n" for k, v in sorted(SHARED_DEFINES.items()))
            + "".join(f"#define {k} {v}\n" for k, v in sorted((defines or {}).items())))
    return head + body, files


def _expand(name: str, files: list[str], stack: set[str]) -> str:
    path = GLSL_ROOT / name
    if name in stack:
        raise ShaderError(f"glsl/{name}: circular #include")
    if not path.is_file():
        raise ShaderError(f"glsl/{name}: file not found")
    index = len(files)
    files.append(name)
    out = [f"#line 1 {index}\n"]
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        match = _INCLUDE.match(line)
        if match:
            out.append(_expand(match.group(1), files, stack | {name}))
            out.append(f"#line {number + 1} {index}\n")
        else:
            out.append(line + "\n")
    return "".join(out)


def _explain(error: Exception, files: list[str]) -> str:
    """Rewrite Mesa/NVIDIA style `K:LINE(COL)` or `K(LINE)` locations into glsl/file:LINE."""
    def repl(match):
        index, line = int(match.group(1)), match.group(2)
        name = files[index] if index < len(files) else f"<source {index}>"
        return f"glsl/{name}:{line}"
    return re.sub(r"\b(\d+)[:(](\d+)\)?(?:\(\d+\))?", repl, str(error))


def program(worker, vertex: str | None = None, fragment: str | None = None, compute: str | None = None,
            defines: dict | None = None, geometry: str | None = None):
    """A compiled program, cached on the worker for the life of its context. `geometry` adds a geometry
    stage between vertex and fragment (conservative rasterization emulates itself there)."""
    key = repr((vertex, fragment, compute, sorted((defines or {}).items()), geometry))
    cached = worker.cache.get(key)
    if cached is not None:
        return cached
    ctx = worker.ctx
    sources = {}
    for stage, name in (("vertex", vertex), ("geometry", geometry), ("fragment", fragment), ("compute", compute)):
        if name:
            sources[stage] = expand(name, defines)
    try:
        if compute:
            prog = ctx.compute_shader(sources["compute"][0])
        else:
            prog = ctx.program(vertex_shader=sources["vertex"][0], fragment_shader=sources["fragment"][0],
                               geometry_shader=sources["geometry"][0] if geometry else None)
    except Exception as exc:
        stage_files = [files for _, files in sources.values()]
        # Source-string numbers are per stage; try each stage's table and keep the first that maps.
        message = str(exc)
        for files in stage_files:
            message = _explain(exc, files)
            if "glsl/" in message:
                break
        raise ShaderError(f"GLSL compile failed ({', '.join(n for n in (vertex, geometry, fragment, compute) if n)}):\n"
                          f"{message}") from None
    worker.cache[key] = prog
    return prog


def set_uniforms(prog, values: dict) -> None:
    """Set the uniforms the program actually uses (the compiler drops unused ones, and that is fine)."""
    for name, value in values.items():
        if name in prog:
            prog[name].value = value


def bind_samplers(prog, samplers: dict, first_unit: int = 0) -> int:
    """Bind name → texture to consecutive texture units for the samplers the program uses; returns the
    next free unit."""
    unit = first_unit
    for name, tex in samplers.items():
        if name in prog:
            tex.use(location=unit)
            prog[name].value = unit
            unit += 1
    return unit
