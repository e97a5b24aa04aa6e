"""Per-light structures by name. A technique lists the names it needs (`Technique.needs`); the pipeline builds
each once per light view, before the technique's visibility step, and hands them over in
`LightContext.structures`. A structure module registers a builder `build(frame, lc) -> object`."""
from __future__ import annotations

from typing import Callable

BUILDERS: dict[str, Callable] = {}


def structure(name: str):
    """Decorator: register `build(frame, lc)` as the builder of structure `name`."""
    def register(build):
        BUILDERS[name] = build
        return build
    return register


def build(name: str, frame, lc):
    try:
        builder = BUILDERS[name]
    except KeyError:
        raise KeyError(f"No structure builder named '{name}' (known: {', '.join(BUILDERS)})") from None
    return builder(frame, lc)


from . import conservative_map, depth_map  # noqa: E402,F401  (register their builders)
