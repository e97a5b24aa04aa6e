"""The protocol every shadow technique follows.

A technique declares which per-light structures it needs (the pipeline builds only those) and turns them
into a visibility V ∈ [0, 1] for every pixel this light reaches. It writes V into `out` (an R32F texture
the size of the image); pixels the light does not reach are ignored downstream.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..core.light_shape import light_shape_uniforms  # noqa: F401  (techniques import it from here)
from ..core.lightview import LightView
from ..structures.depth_map import DEPTH_MAP  # noqa: F401  (the default need; techniques import it from here)
from ..core.options import Option  # noqa: F401  (techniques declare their options with it)
from ..core.snapshot import Light

MAP_SIZE_SWEEP = tuple({"shadow_map_size": n} for n in (256, 512, 1024, 2048))


@dataclass
class LightContext:
    light: Light
    view: LightView
    irradiance: object                  # RGBA32F texture: unoccluded E (rgb) and its scalar weight (a)
    receivers: tuple                    # world AABB (lo, hi) of the pixels this light reaches
    casters: tuple | None               # world AABB of the casters, None when there are none
    uniforms: dict                      # light-view uniforms plus bias settings
    # Where the frame's visible pixels lie against flat and convex objects (lightview.receiver_sides): what
    # shadowing_caster_bounds needs to leave out a floor or a room.
    receiver_sides: object = None
    # The light is seen through several views (its single view and cube faces): its receivers surround it.
    split: bool = False
    # The lit points (and their lifted points, world, N × 3) this view holds, where the pipeline read them back
    # (a clamped single view, a cube face); None where only the `receivers` box is known.
    receiver_points: Any = None
    # This view's part of the light's lit pixels (1 for a light seen through its single view): what a work
    # budget meant for the light (SSM's ssm_budget) is split by, so that a light's stand-ins and cube faces
    # together cost no more than one view would.
    share: float = 1.0
    # Distance from a local light's centre to the nearest lit point this view holds (None for a sun): what
    # decides where a sphere light's REFERENCE samples lie (averaged._fills_ball).
    nearest_receiver: float | None = None
    structures: dict = field(default_factory=dict)
    # A coloured visibility (RGBA32F texture, rgb per channel) for a textured light: Combined then uses it
    # channel by channel, while `out` keeps the scalar (luminance-weighted) visibility.
    visibility_rgb: object | None = None
    # Statistics the technique reports for this light (with settings.collect_stats or debug passes on); the
    # pipeline lists them in FrameResult.stats["per_light"].
    stats: dict = field(default_factory=dict)
    # Debug passes this light produced: name → (H, W, C) float32 array (row 0 at the bottom). With several
    # lights the pipeline keeps the per-pixel maximum.
    debug: dict = field(default_factory=dict)


class Technique:
    identifier = ""
    label = ""
    description = ""
    needs: tuple[str, ...] = (DEPTH_MAP,)
    options: tuple[Option, ...] = ()    # the technique's own settings
    # Shared settings (core.settings.SHARED) beyond map size and bias that only some techniques read; the
    # panel shows them beside the technique's options.
    reads_shared: tuple[str, ...] = ()
    debug_passes: tuple = ()            # (name, channels, channel ids, Blender type) written with debug on
    # The technique's cheap mode for the viewport's first frame after a change (settings changes).
    coarse: dict = {}
    # Configurations the benchmark's --sweep traces (settings changes; RenderSettings fields or options).
    sweep: tuple[dict, ...] = MAP_SIZE_SWEEP
    # The technique works from the map of the light's centre, whose rays tell nothing about a receiver that has
    # the centre below its horizon: the pipeline gives such receivers a view from the part of the emitter
    # they see instead (a sun's: core.lightview.sun_rim_faces; an area or sphere light's: local_rim_lights).
    rim_views = False
    # The technique fits views of its own from points of the light (REFERENCE's samples): on smooth triangles
    # the pipeline then reads back where the lit pixels' shadow rays leave from (LightContext.receiver_points,
    # the terminator lift included), so that those views hold a lifted start instead of losing it off the map.
    fits_sample_views = False

    def needs_for(self, settings) -> tuple:
        """The structures to build for `settings` (names, or structures.need(NAME, **params) where options
        decide a builder's parameters); the pipeline asks this. Default: the class's `needs`."""
        return tuple(self.needs)

    def visibility(self, frame, lc: LightContext, out) -> None:
        raise NotImplementedError
