"""The one list of render passes: used to register them with Blender (update_render_passes), to add and
write them when rendering, and to name the layers of the command line's EXR files."""
from __future__ import annotations

from typing import Iterator

from .options import technique_debug_passes

# name, channels, channel ids, Blender pass type
BASE_PASSES = (
    ("Combined", 4, "RGBA", "COLOR"),
    ("Depth", 1, "Z", "VALUE"),
    ("Visibility", 1, "X", "VALUE"),
    ("Unshadowed", 3, "RGB", "COLOR"),
)
DEBUG_PASSES = (
    ("Irradiance", 3, "RGB", "COLOR"),  # Σ over lights of the unoccluded irradiance E (W/m²)
)


def render_passes(settings) -> Iterator[tuple[str, int, str, str]]:
    yield from BASE_PASSES
    if getattr(settings, "debug_passes", False):
        yield from DEBUG_PASSES
        yield from technique_debug_passes(getattr(settings, "technique", ""))
