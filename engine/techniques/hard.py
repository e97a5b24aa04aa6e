"""HARD: one depth map from the light's centre, one comparison per pixel (Williams 1978)."""
from .base import Technique


class Hard(Technique):
    identifier = "HARD"
    label = "Hard shadow map"
    description = "Standard shadow map from the light centre: hard shadows, the speed baseline"
    rim_views = True

    def visibility(self, frame, lc, out):
        frame.dispatch("hard/visibility.comp", lc.uniforms, samplers={
            "g_irradiance": lc.irradiance, "u_depth_map": lc.structures["depth_map"]}, images={0: out})
