"""Settings that techniques declare, and the catalogue the core reads them from.

Techniques live in a layer above the core, so the core never imports them: the technique registry
(`engine/techniques/__init__.py`) enters each technique's identifier, options and debug passes here when it is
imported, and settings validation and the pass list read this catalogue.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Option:
    """A setting a technique declares: becomes a scene.penumbra property, a `--set` name on the command line
    and a RenderSettings.option() value. Prefix names with the technique (e.g. `bp_budget`)."""
    name: str
    default: Any                        # bool, int, float, or str (an enum with `items`, else free text)
    label: str
    description: str = ""
    min: float | None = None
    max: float | None = None
    items: tuple = ()                   # enum: ((identifier, label, description), …)
    soft_min: float | None = None       # slider range in Blender's UI (within min … max)
    soft_max: float | None = None

    def allowed(self) -> str:
        """The allowed values in words, as messages and help print them."""
        if self.items:
            return "one of " + ", ".join(i[0] for i in self.items)
        if isinstance(self.default, bool):
            return "true/false"
        if isinstance(self.default, str):
            return "any text"
        return range_text(self.min, self.max)

    def check(self, value) -> None:
        """Raise ValueError naming the option when `value` is not allowed."""
        if self.items:
            allowed = [i[0] for i in self.items]
            if value not in allowed:
                raise ValueError(f"Setting '{self.name}' = {value!r}: choose one of {', '.join(allowed)}")
            return
        if isinstance(self.default, bool):
            if not isinstance(value, (bool, int)):
                raise ValueError(f"Setting '{self.name}' expects true/false, got {value!r}")
            return
        if isinstance(self.default, str):
            if not isinstance(value, str):
                raise ValueError(f"Setting '{self.name}' expects text, got {value!r}")
            return
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise ValueError(f"Setting '{self.name}' = {value} is out of range ({self.allowed()})")


def range_text(lo=None, hi=None) -> str:
    """'lo … hi', '≥ lo' or '≤ hi', numbers written without a needless '.0'."""
    def num(x):
        return str(int(x)) if float(x).is_integer() else str(x)
    if lo is not None and hi is not None:
        return f"{num(lo)} … {num(hi)}"
    if lo is not None:
        return f"≥ {num(lo)}"
    return f"≤ {num(hi)}" if hi is not None else "any number"


# identifier -> technique object (anything with `identifier`, `options` and `debug_passes`), in the order the
# UI lists them. The technique registry fills it; it is the same dict as techniques.TECHNIQUES.
CATALOGUE: dict = {}


def known_options() -> dict[str, Option]:
    """Every declared option by name."""
    return {opt.name: opt for t in CATALOGUE.values() for opt in t.options}


def technique_identifiers() -> list[str]:
    return list(CATALOGUE)


def technique_options(identifier: str) -> tuple:
    technique = CATALOGUE.get(identifier)
    return tuple(technique.options) if technique is not None else ()


def technique_debug_passes(identifier: str) -> tuple:
    technique = CATALOGUE.get(identifier)
    return tuple(technique.debug_passes) if technique is not None else ()
