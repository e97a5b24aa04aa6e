"""PCF: percentage-closer filtering with a fixed kernel (Reeves, Salesin, Cook 1987), bilinear taps."""
from ..structures.depth_map import FACET_MAP
from .base import DEPTH_MAP, MAP_SIZE_SWEEP, Option, Technique


class Pcf(Technique):
    identifier = "PCF"
    label = "PCF"
    description = "Fixed-size percentage-closer filter: uniform blur, ignores light size and distance"
    rim_views = True
    options = (
        Option("pcf_radius", 2.0, "Radius", "PCF kernel radius in texels", min=0.0, max=256.0),
        Option("pcf_taps", 5, "Taps", "Taps per side of the square PCF kernel (bilinear each)", min=1, max=33),
    )
    needs = (DEPTH_MAP, FACET_MAP)
    sweep = MAP_SIZE_SWEEP + tuple({"pcf_radius": r} for r in (1.0, 2.0, 4.0))

    def visibility(self, frame, lc, out):
        s = frame.settings
        frame.dispatch("pcf/visibility.comp", {**lc.uniforms, "u_radius": float(s.option("pcf_radius")),
                                               "u_taps": int(s.option("pcf_taps"))},
                       samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures[DEPTH_MAP],
                                 "u_facet_map": lc.structures[FACET_MAP]},
                       images={0: out})
