"""Per-light structures by name. A technique declares what it needs (`Technique.needs`, or
`Technique.needs_for(settings)` when options decide); the pipeline builds each once per light view, before the
technique's visibility step, and hands them over in `LightContext.structures` under their names.

A structure module registers a builder `build(frame, lc, **params) -> object` with `@structure(NAME)`,
naming the structures it reads (`requires`): those are built first, with their default parameters unless
the technique asks for them itself. A need is a name, or `need(NAME, **params)` for a builder that takes
parameters (the number of peeled layers, the occluder-map size). Every built structure reports the GPU
memory it holds (`nbytes`), which the pipeline lists in FrameResult.stats["structure_bytes"]."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..gpu.frame import resource_bytes


@dataclass(frozen=True)
class Need:
    name: str
    params: tuple = ()          # sorted (key, value) pairs, hashable

    @property
    def kwargs(self) -> dict:
        return dict(self.params)


def need(name: str, **params) -> Need:
    return Need(name, tuple(sorted(params.items())))


@dataclass(frozen=True)
class Builder:
    build: Callable
    requires: tuple[str, ...]


BUILDERS: dict[str, Builder] = {}


def structure(name: str, requires: tuple[str, ...] = ()):
    """Decorator: register `build(frame, lc, **params)` as the builder of structure `name`."""
    def register(build):
        BUILDERS[name] = Builder(build, tuple(requires))
        return build
    return register


def _builder(name: str) -> Builder:
    try:
        return BUILDERS[name]
    except KeyError:
        raise KeyError(f"No structure builder named '{name}' (known: {', '.join(BUILDERS)})") from None


def plan(needs) -> list[Need]:
    """The needs in build order: each after the structures it requires, each name once. A name asked for
    twice with different parameters is an error (one light view holds one structure of each name)."""
    asked: dict[str, Need] = {}
    for n in needs:
        n = n if isinstance(n, Need) else Need(n)
        _builder(n.name)
        if n.name in asked and asked[n.name] != n:
            raise ValueError(f"Structure '{n.name}' requested with different parameters: "
                             f"{asked[n.name].kwargs} and {n.kwargs}")
        asked[n.name] = n
    order: list[Need] = []

    def visit(name: str, stack: tuple):
        if name in stack:
            raise ValueError(f"Structure '{name}' requires itself ({' → '.join(stack + (name,))})")
        if any(o.name == name for o in order):
            return
        for dep in _builder(name).requires:
            visit(dep, stack + (name,))
        order.append(asked.get(name, Need(name)))
    for name in asked:
        visit(name, ())
    return order


def build(name, frame, lc, **params):
    """Build one structure (`name` or a Need) for the light view of `lc`."""
    if isinstance(name, Need):
        name, params = name.name, {**name.kwargs, **params}
    return _builder(name).build(frame, lc, **params)


def nbytes(obj) -> int:
    """GPU memory a built structure holds: its own `nbytes` when it reports one, else its textures'."""
    return resource_bytes(obj)


from . import conservative_map, depth_map, peeled_layers, hsm, lit_umbra, mssm, microrects, coverage, ysm, ssm_maps, soft_shadow_map, solid_exits  # noqa: E402,F401  (register builders)
