"""Render settings as a plain dataclass: what the pipeline reads. No bpy here.

One mechanism describes every setting: an `Option` (name, default, label, range). The settings every
technique shares are declared in `SHARED` below and are RenderSettings fields; each technique declares its
own (Technique.options), which RenderSettings keeps in `extras`. Blender's properties (ui/properties.py), the
command line's `--set` and its help, and `validate` are all generated from these Options, so defaults and
ranges live in one place.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from .options import Option, known_options, technique_identifiers, technique_options

# The settings every technique reads, in the order the UI and the help list them.
SHARED = (
    Option("shadow_map_size", 1024, "Shadow Map Size", "Texels along the longer side of each light's shadow map",
           min=16, max=16384, soft_min=128, soft_max=4096),
    Option("bias", 1.0, "Bias", "Depth bias in shadow-map texels, scaled by the receiver's slope",
           min=0.0, max=100.0),
    Option("normal_offset", 0.25, "Normal Offset", "Receiver offset along its normal, in shadow-map texels",
           min=0.0, max=100.0),
    Option("seed", 0, "Seed", "Seed of the techniques' sample patterns", min=0),
    Option("early_skip", False, "Skip Lit/Umbra Pixels",
           "PCSS and REFERENCE skip their gather where a conservative test proves a pixel fully lit or in umbra "
           "(same result, less work)"),
    Option("debug_passes", False, "Debug Passes", "Also write the technique's debug passes"),
    Option("antialiasing", True, "Anti-aliasing",
           "4× multisampled G-buffer with one visibility per pixel (Schwarz & Stamminger 2008, §7): shading per "
           "sample, averaged, for Combined, Unshadowed and Irradiance"),
    Option("aa_depth_threshold", 0.01, "AA Depth Threshold",
           "Relative camera-depth difference (τ) under which a sample shares its pixel's visibility; samples "
           "beyond it take the 4-neighbour of closest depth", min=0.0, max=1.0),
    Option("aa_visibility_sample", "CENTER", "AA Visibility Sample",
           "Where each pixel's one visibility is computed when anti-aliasing", items=(
               ("CENTER", "Pixel Centre", "A second, single-sample G-buffer at pixel centres: the techniques' "
                "input and the Depth and Visibility passes are those of a frame without anti-aliasing"),
               ("FIRST", "First Sample", "The first multisample (the paper's choice; GL puts it off the pixel "
                "centre, which shifts silhouettes in the Depth and Visibility passes by up to 0.4 px)"))),
)
_SHARED = {o.name: o for o in SHARED}

# Stored settings that were renamed: old name → new name. The load_post handler (ui/versioning.py) moves
# values saved under an old name in a .blend, and `--set OLD=…` is accepted with a notice.
RENAMED = {
    "reference_samples": "averaged_light_samples",
    "reference_weighted": "averaged_weighted",
}


@dataclass
class RenderSettings:
    technique: str = "PCSS"
    shadow_map_size: int = _SHARED["shadow_map_size"].default
    bias: float = _SHARED["bias"].default
    normal_offset: float = _SHARED["normal_offset"].default
    seed: int = _SHARED["seed"].default
    early_skip: bool = _SHARED["early_skip"].default
    # passes beyond Combined/Depth/Visibility/Unshadowed
    debug_passes: bool = _SHARED["debug_passes"].default
    antialiasing: bool = _SHARED["antialiasing"].default
    aa_depth_threshold: float = _SHARED["aa_depth_threshold"].default
    aa_visibility_sample: str = _SHARED["aa_visibility_sample"].default
    # techniques record per-light statistics in FrameResult.stats["per_light"] (may cost a readback)
    collect_stats: bool = False
    # Settings a technique declares itself (Technique.options), by option name; unset ones take defaults.
    extras: dict = field(default_factory=dict)

    def with_(self, **changes) -> "RenderSettings":
        """A copy with fields changed; names of technique options go into `extras`."""
        own = set(self.field_names())
        extras = dict(self.extras)
        extras.update({k: v for k, v in changes.items() if k not in own})
        return replace(self, **{k: v for k, v in changes.items() if k in own}, extras=extras)

    def option(self, name: str):
        """Value of a technique option (Technique.options), its default when unset."""
        if name in self.extras:
            return self.extras[name]
        try:
            return known_options()[name].default
        except KeyError:
            raise KeyError(f"No technique declares an option '{name}'") from None

    def effective(self) -> dict:
        """The fields and the options of this technique, defaults filled in (plus any other option set): two
        settings that render alike give equal dicts, whether an option was set to its default or left unset."""
        values = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extras"}
        values.update({o.name: self.option(o.name) for o in technique_options(self.technique)})
        values.update({k: v for k, v in self.extras.items() if k not in values})
        return values

    @classmethod
    def field_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    def validate(self) -> None:
        """Raise ValueError naming the setting when a value is out of its range."""
        identifiers = technique_identifiers()
        if self.technique not in identifiers:
            raise ValueError(f"Unknown technique '{self.technique}'; choose one of {', '.join(identifiers)}")
        for opt in SHARED:
            opt.check(getattr(self, opt.name))
        options = known_options()
        for name, value in self.extras.items():
            if name not in options:
                hint = f" (renamed '{RENAMED[name]}')" if name in RENAMED else ""
                raise ValueError(f"Unknown setting '{name}'{hint}")
            options[name].check(value)


def setting_options() -> list[Option]:
    """Every setting a user can set (shared, then each technique's), as Options."""
    return list(SHARED) + list(known_options().values())


def setting_option(name: str) -> Option:
    """The Option of a shared or a technique's setting."""
    try:
        return next(o for o in setting_options() if o.name == name)
    except StopIteration:
        raise KeyError(f"No setting '{name}'") from None
