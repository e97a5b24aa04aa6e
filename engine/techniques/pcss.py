"""PCSS: percentage-closer soft shadows (Fernando 2005): blocker search, penumbra estimate, variable PCF.
The main foil of the soft-shadow-map papers."""
from ..core.light_shape import light_reach_box
from ..structures import need
from ..structures.depth_map import BACK_DEPTH_MAP, FACET_MAP
from ..structures.lit_umbra import LIT_UMBRA
from .base import DEPTH_MAP, MAP_SIZE_SWEEP, Option, Technique, light_shape_uniforms


class Pcss(Technique):
    identifier = "PCSS"
    label = "PCSS"
    description = "Blocker search and variable-size PCF (Fernando 2005): plausible, not exact, soft shadows"
    rim_views = True
    options = (
        # 64: the search's taps are weighted towards its centre and its depths are midpoints, so its mean rests
        # on fewer taps than their count; 32 left blotches (tests/test_grazing.py's outlier share on suzanne
        # 5.8 %, 4.5 % at 64); 64 cost 5–25 % more of PCSS's frame time on llvmpipe at 128².
        Option("pcss_blocker_samples", 64, "Blocker Samples", "Depth-map samples of the blocker search",
               min=1, max=1024),
        # 512: where the taps' irradiance weights vary strongly across the light (one seen low over the
        # receiver) the weighted mean converges slowly, and 128 taps shifted `grazing`'s penumbra sideways by up
        # to 0.03 (one side too light, the other too dark). At 128² against Cycles 1024 spp, 128 → 512 taps:
        # grazing 0.0191 → 0.0118, tilted 0.0160 → 0.0125, plane and textured 0.0166 → 0.0115, thin 0.0309 →
        # 0.0269, balls 0.0325 → 0.0299, silhouette 0.0462 → 0.0431, the other seven 0.3–6 % better or
        # unchanged (slab +0.0001); all 14 frames summed 1.23× on llvmpipe (grazing and tilted at 512²: 1.5× and
        # 1.4×). Fuzz 21000–21039 unchanged in sum (1.965 → 1.972), 2/40 over bound both ways.
        Option("pcss_filter_samples", 512, "Filter Samples", "Depth-map comparisons of the variable filter",
               min=1, max=4096),
        # The cap is a bias trade-off, not a noise or cost guard (the tap counts are fixed; 4x the taps moved the
        # fuzz errors below by at most 0.02). Below the cap the kernels act as a smaller light's: a penumbra wider
        # than it comes out too dark (stress big_light; under 2-3 rad suns, fuzz 8134 0.233 / 8335 0.223 at 0.1,
        # 0.064 / 0.111 at 0.5, 0.103 / 0.130 at 1.0, the region the light's extent and the casters' depth range
        # allow). Above it the filter, sized by one mean blocker depth, reads lit texels on rays that a caster
        # at another depth blocks: fuzz 8369 (1.6 rad sun over stacked casters) 0.057 at 0.1, 0.369 at 0.5; and
        # with a light almost touching its caster (stress near_light) the kernels reach past the map, whose
        # outside counts as empty: umbra leak 0.094 at 0.5, none at 0.1.
        Option("pcss_max_radius", 0.1, "Max Radius",
               "Cap on the blocker search's radius, as a fraction of the shadow map; raising it (0.5) suits very "
               "wide lights over lone casters", min=0.001, max=1.0),
        # The filter's own cap (ours), measured with 128 filter taps. Once the search has found blockers within its
        # reach, the penumbra they cast may be wider than that reach (a cube or plane under a light as wide as
        # they are). At 128² against Cycles 1024 spp, filter cap 0.1 → 0.2 and 64 → 128 taps: cube 0.088 →
        # 0.048, plane and textured 0.069 → 0.017, silhouette 0.071 → 0.046, grazing 0.030 → 0.019, tilted
        # 0.021 → 0.016, suzanne 0.040 → 0.035, balls 0.036 → 0.033, thin 0.037 → 0.031, slab 0.067 → 0.060; no
        # scene worse by more than 0.0004 (city). The cap alone left suzanne's wider penumbrae stepped (the
        # outlier share of tests/test_grazing.py 4.5 % → 5.3 %; with 128 taps 3.2 %). Fuzz 14000–14039 and
        # 15000–15039: 25 scenes better by more than 0.001, 6 worse, mean 0.0287 → 0.0269; 8369 (the stacked
        # casters above) 0.056 → 0.145 within its bound of 0.155; 8134 and 8335 0.233 / 0.223 → 0.157 / 0.162.
        # Stress big_light passes (0.035).
        Option("pcss_filter_max_radius", 0.2, "Max Filter Radius",
               "Cap on the filter's radius, as a fraction of the shadow map (never below Max Radius): penumbrae "
               "wider than it come out too dark", min=0.001, max=1.0),
        Option("pcss_midpoint", True, "Midpoint Blockers",
               "Take a blocker's depth halfway through its caster (between the faces the light centre sees and the "
               "back faces behind them), where a rounded caster's outline lies; off: the nearest surface, as in "
               "Fernando 2005"),
    )
    coarse = {"pcss_blocker_samples": 16, "pcss_filter_samples": 16}
    sweep = MAP_SIZE_SWEEP + tuple({"pcss_blocker_samples": b, "pcss_filter_samples": f}
                                   for b, f in ((16, 32), (32, 64), (64, 128), (64, 512)))

    reads_shared = ("early_skip",)

    def needs_for(self, settings) -> tuple:
        maps = (DEPTH_MAP, FACET_MAP) + ((BACK_DEPTH_MAP,) if settings.option("pcss_midpoint") else ())
        if not settings.early_skip:
            return maps
        # Every texel of the (capped) blocker-search area nearer than the receiver's plane is a blocker,
        # whether or not it lies in the pyramid towards the light: the classes must not narrow the area.
        # Lit where the search finds nothing; umbra only where the filter, reaching further, finds only blockers.
        return maps + (need(LIT_UMBRA, narrow=False, cap=float(settings.option("pcss_max_radius")),
                            umbra_cap=_filter_cap(settings)),)

    def visibility(self, frame, lc, out):
        s = frame.settings
        classes = lc.structures.get(LIT_UMBRA)
        back = lc.structures.get(BACK_DEPTH_MAP)
        frame.dispatch("pcss/visibility.comp", {
            **lc.uniforms, **light_shape_uniforms(lc.light, lc.view),
            "u_blocker_samples": int(s.option("pcss_blocker_samples")),
            "u_filter_samples": int(s.option("pcss_filter_samples")),
            "u_max_radius": float(s.option("pcss_max_radius")) * max(lc.view.width, lc.view.height),
            "u_filter_max_radius": _filter_cap(s) * max(lc.view.width, lc.view.height),
            "u_facet_light": light_reach_box(lc.light, lc.view)},
            samplers={"g_irradiance": lc.irradiance, "u_depth_map": lc.structures[DEPTH_MAP],
                      "u_facet_map": lc.structures[FACET_MAP],
                      **({"u_classes": classes.classes} if classes else {}),
                      **({"u_back_map": back} if back is not None else {})},
            images={0: out}, defines={"EARLY_SKIP": int(classes is not None), "MIDPOINT": int(back is not None)})


def _filter_cap(settings) -> float:
    """The filter's cap: pcss_filter_max_radius, and never short of the search's (pcss_max_radius)."""
    return max(float(settings.option("pcss_max_radius")), float(settings.option("pcss_filter_max_radius")))
