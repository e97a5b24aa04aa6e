"""PCF: percentage-closer filtering with a fixed kernel (Reeves, Salesin, Cook 1987), bilinear taps."""
from .base import MAP_SIZE_SWEEP, Technique


class Pcf(Technique):
    identifier = "PCF"
    label = "PCF"
    description = "Fixed-size percentage-closer filter: uniform blur, ignores light size and distance"
    sweep = MAP_SIZE_SWEEP + tuple({"pcf_radius": r} for r in (1.0, 2.0, 4.0))

    def visibility(self, frame, lc, out):
        s = frame.settings
        frame.dispatch("pcf/visibility.comp", {**lc.uniforms, "u_radius": float(s.pcf_radius),
                                               "u_taps": int(s.pcf_taps)},
                       samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures["depth_map"]},
                       images={0: out})
