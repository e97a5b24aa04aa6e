"""Render settings as a plain dataclass: what the pipeline reads. `ui/properties.py` mirrors these fields as
Blender properties (scene.penumbra) and converts with `settings_from_scene`; the command line fills them
from its arguments. No bpy here."""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from .options import known_options, technique_identifiers


@dataclass
class RenderSettings:
    technique: str = "PCSS"
    shadow_map_size: int = 1024          # texels along the longer side of every light's map
    bias: float = 1.0                    # depth bias in texels, scaled by the receiver slope
    normal_offset: float = 0.5           # receiver offset along its geometric normal, in texels
    # PCF
    pcf_radius: float = 2.0              # kernel radius in texels
    pcf_taps: int = 5                    # taps per side of the square kernel (bilinear each)
    # PCSS (Fernando 2005)
    pcss_blocker_samples: int = 32
    pcss_filter_samples: int = 64
    pcss_max_radius: float = 0.1         # cap on search and filter radius, as a fraction of the map size
    # REFERENCE: average of N hard shadow maps from stratified points on the light
    reference_samples: int = 64
    reference_weighted: bool = True      # weight each sample by its unoccluded contribution at the pixel
    seed: int = 0
    # passes beyond Combined/Depth/Visibility/Unshadowed
    debug_passes: bool = False
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

    @classmethod
    def field_names(cls) -> list[str]:
        return [f.name for f in fields(cls)]

    def validate(self) -> None:
        """Raise ValueError naming the setting when a value is out of its range."""
        identifiers = technique_identifiers()
        if self.technique not in identifiers:
            raise ValueError(f"Unknown technique '{self.technique}'; choose one of {', '.join(identifiers)}")
        checks = [
            ("shadow_map_size", 16 <= self.shadow_map_size <= 16384, "16 … 16384"),
            ("reference_samples", 1 <= self.reference_samples <= 4096, "1 … 4096"),
            ("pcf_taps", 1 <= self.pcf_taps <= 33, "1 … 33"),
            ("pcf_radius", 0.0 <= self.pcf_radius <= 256.0, "0 … 256"),
            ("pcss_blocker_samples", 1 <= self.pcss_blocker_samples <= 1024, "1 … 1024"),
            ("pcss_filter_samples", 1 <= self.pcss_filter_samples <= 4096, "1 … 4096"),
            ("bias", 0.0 <= self.bias <= 100.0, "0 … 100"),
            ("pcss_max_radius", 0.0 < self.pcss_max_radius <= 1.0, "0 … 1"),
            ("normal_offset", 0.0 <= self.normal_offset <= 100.0, "0 … 100"),
        ]
        for name, ok, allowed in checks:
            if not ok:
                raise ValueError(f"Setting '{name}' = {getattr(self, name)} is out of range ({allowed})")
        options = known_options()
        for name, value in self.extras.items():
            if name not in options:
                raise ValueError(f"Unknown setting '{name}'")
            options[name].check(value)
