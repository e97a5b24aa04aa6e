"""PCSS: percentage-closer soft shadows (Fernando 2005): blocker search, penumbra estimate, variable PCF.
The main foil of the soft-shadow-map papers."""
from ..structures import need
from ..structures.lit_umbra import LIT_UMBRA
from .base import DEPTH_MAP, MAP_SIZE_SWEEP, Option, Technique, light_shape_uniforms


class Pcss(Technique):
    identifier = "PCSS"
    sun_rim_views = True
    label = "PCSS"
    description = "Blocker search and variable-size PCF (Fernando 2005): plausible, not exact, soft shadows"
    options = (
        Option("pcss_blocker_samples", 32, "Blocker Samples", "Depth-map samples of the blocker search",
               min=1, max=1024),
        Option("pcss_filter_samples", 64, "Filter Samples", "Depth-map comparisons of the variable filter",
               min=1, max=4096),
        Option("pcss_max_radius", 0.1, "Max Radius",
               "Cap on the search and filter radius, as a fraction of the shadow map", min=0.001, max=1.0),
    )
    coarse = {"pcss_blocker_samples": 16, "pcss_filter_samples": 16}
    sweep = MAP_SIZE_SWEEP + tuple({"pcss_blocker_samples": b, "pcss_filter_samples": f}
                                   for b, f in ((16, 32), (32, 64), (64, 128)))

    reads_shared = ("early_skip",)

    def needs_for(self, settings) -> tuple:
        if not settings.early_skip:
            return (DEPTH_MAP,)
        # Every texel of the (capped) blocker-search area nearer than the receiver's plane is a blocker,
        # whether or not it lies in the pyramid towards the light: the classes must not narrow the area.
        return (DEPTH_MAP, need(LIT_UMBRA, narrow=False, cap=float(settings.option("pcss_max_radius"))))

    def visibility(self, frame, lc, out):
        s = frame.settings
        classes = lc.structures.get(LIT_UMBRA)
        frame.dispatch("pcss/visibility.comp", {
            **lc.uniforms, **light_shape_uniforms(lc.light, lc.view),
            "u_blocker_samples": int(s.option("pcss_blocker_samples")),
            "u_filter_samples": int(s.option("pcss_filter_samples")),
            "u_max_radius": float(s.option("pcss_max_radius")) * max(lc.view.width, lc.view.height)},
            samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures[DEPTH_MAP],
                      **({"u_classes": classes.classes} if classes else {})},
            images={0: out}, defines={"EARLY_SKIP": int(classes is not None)})
