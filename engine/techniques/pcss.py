"""PCSS: percentage-closer soft shadows (Fernando 2005): blocker search, penumbra estimate, variable PCF.
The main foil of the soft-shadow-map papers."""
from .base import MAP_SIZE_SWEEP, Technique, light_shape_uniforms


class Pcss(Technique):
    identifier = "PCSS"
    label = "PCSS"
    description = "Blocker search and variable-size PCF (Fernando 2005): plausible, not exact, soft shadows"
    coarse = {"pcss_blocker_samples": 16, "pcss_filter_samples": 16}
    sweep = MAP_SIZE_SWEEP + tuple({"pcss_blocker_samples": b, "pcss_filter_samples": f}
                                   for b, f in ((16, 32), (32, 64), (64, 128)))

    def visibility(self, frame, lc, out):
        s = frame.settings
        frame.dispatch("pcss/visibility.comp", {
            **lc.uniforms, **light_shape_uniforms(lc.light, lc.view),
            "u_blocker_samples": int(s.pcss_blocker_samples), "u_filter_samples": int(s.pcss_filter_samples),
            "u_max_radius": float(s.pcss_max_radius) * max(lc.view.width, lc.view.height)},
            samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures["depth_map"]},
            images={0: out})
