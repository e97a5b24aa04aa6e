"""PCSS: percentage-closer soft shadows (Fernando 2005): blocker search, penumbra estimate, variable PCF.
The main foil of the soft-shadow-map papers."""
from .base import MAP_SIZE_SWEEP, Option, Technique, light_shape_uniforms


class Pcss(Technique):
    identifier = "PCSS"
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

    def visibility(self, frame, lc, out):
        s = frame.settings
        frame.dispatch("pcss/visibility.comp", {
            **lc.uniforms, **light_shape_uniforms(lc.light, lc.view),
            "u_blocker_samples": int(s.option("pcss_blocker_samples")),
            "u_filter_samples": int(s.option("pcss_filter_samples")),
            "u_max_radius": float(s.option("pcss_max_radius")) * max(lc.view.width, lc.view.height)},
            samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures["depth_map"]},
            images={0: out})
