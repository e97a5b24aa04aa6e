"""SSM: soft shadow maps (Atty, Holzschuch, Lapierre, Hasenfratz, Hansen, Sillion 2006, "Soft Shadow Maps:
Efficient Sampling of Light Source Visibility").

Per light (Fig. 3 of the paper):
  1. occluder map (casters) and receiver depth maps (receivers) from the light centre, aligned with the
     light (§3.1–3.2), with square texels (deviation: the paper's texels of the light's aspect ratio, the
     `ssm_texels` option, make a sliver light's texels long on one side; see ssm_maps.ssm_view);
  2. every occluder texel becomes a micro-patch parallel to the light; its penumbra extent on the
     soft-shadow-map plane is an axis-aligned rectangle (§3.3; the paper computes it on the CPU, here a
     compute pass does, with the work estimate that can lower the map resolution: only the patch count and
     the work are read back);
  3. scatter: for every SSM texel inside that rectangle the patch is back-projected onto the light and the
     hidden fraction added (§3.4) — instanced quads with additive blending (default) or a compute pass with
     fixed-point integer atomics (`ssm_scatter`);
  4. two-sided (§3.5): a second occluder map of the farthest back faces gets its own SSM; merged by maximum;
  5. the SSM is projected onto the receivers in the camera view: V = 1 - occlusion; a receiver lit through its
     own smooth triangle (the terminator lift's start, which the scatter does not reach) takes the hard test of
     the occluder map instead (ours, glsl/ssm/project.comp).

Roles (Object Properties → Penumbra → Shadow Role): micro-patches come from CASTER and BOTH objects,
receivers are the RECEIVER and BOTH pixels the camera sees. The paper separates occluders from receivers
(§1, §6); in a general scene every object is both, so an object does shadow itself here (a monkey's
brow on its eyes, a room's walls on what is inside it under a light outside): a micro-patch counts for a
receiver only if it lies above the receiver's tangent plane, by the slope-scaled bias (the rule
common/light_view.glsl's receiver_depth_at gives every technique, with the Cycles-style terminator lift of
pixel_receiver). The receiver's own surface, a convex object's far side and the staircase of micro-patches
parallel to the light along a steep surface all lie on or below that plane.

Receiver maps (deviation: the paper rasterises one receiver map from the light): built from the camera's
receiver pixels, each splatted into the 2×2 texels its bilinear look-up reads at its tangent plane's depth
there; per texel the nearest and the farthest such receiver are kept with their normals (ssm/receivers.comp),
the scatter sums the occlusion of both (two channels), and a camera pixel takes the one whose depth it
matches, interpolating by depth in between. A surface the camera does not see (a box's top above the floor
inside it) is no receiver, so it cannot stand in for the receivers behind it; the farthest visible receiver
also bounds the penumbra extents (§3.3), so hidden surfaces cost no scatter work. A flat, axis-aligned
caster that every visible receiver lies on the light side of (a ground plane) cannot shadow anything and is
left out of the occluder maps (lightview.shadowing_caster_bounds). Pixels of camera-visible objects that are
not receivers (CASTER role) get V = 1. A light walled off by a closed shell around the camera gets no views at
all (render/pipeline.py, lightview.enclosing_shell): from inside, a wide light's rays leave the shell mostly
through its half turned away from the light, which the front map lacks and the back map's maximum merge
(§3.5) cannot add.

Accumulation precision (appendix A): float32 blending (default); half-float blending, which loses the
contributions of micro-patches hiding less than ~2^-11 of the light once the sum grows (large maps); and
half-float with the paper's workaround: ⌊√M⌋ batches summed separately and then added together.

Lights: rectangle and square exactly; disk, ellipse and sun (disk of directions) exactly in their own view, each
patch's rectangle of the light clipped to the round shape (glsl/ssm/patch.glsl light_share, ours); sphere lights
(point/spot radius) and round lights seen from a cube face or a sun's rim view through their bounding rectangle;
under a spot's cone narrower than its ball, the disk of it each receiver sees (glsl/ssm/patch.glsl spot_share).

Map size (ours, `ssm_refine`): a light whose patches update a texel or two each is a point-like light, whose soft
shadow map is a hard one; its maps are refined up to the shared Shadow Map Size (engine/structures/ssm_maps.py
refined_size), so its edges are drawn as finely as HARD draws them.

Steps 1–3 are per-light structures (engine/structures/ssm_maps.py: maps, patch list and the receiver mask;
soft_shadow_map.py: the scatter), declared by `needs_for` with the options' parameters; this module projects.
"""
from __future__ import annotations

import numpy as np

from ..structures import need
from ..structures.soft_shadow_map import SOFT_SHADOW_MAP
from ..structures.ssm_maps import RECEIVER_MASK, SSM_MAPS, ssm_view  # noqa: F401  (ssm_view: tests use it here)
from .base import Option, Technique

PRECISION_ITEMS = (
    ("FLOAT32", "Float32", "32-bit float blending: exact to ~1e-7 per micro-patch (default)"),
    ("HALF", "Half Float", "16-bit float blending as on 2006 GPUs: contributions below 2^-11 of the running "
                           "sum are lost, so large maps under-shadow (appendix A)"),
    ("HALF_BATCHED", "Half Float, Batched", "16-bit float blending with the paper's workaround: ⌊√M⌋ "
                                            "batches summed separately, then added (appendix A)"),
)


class SoftShadowMaps(Technique):
    identifier = "SSM"
    label = "Soft Shadow Maps"
    description = ("Atty et al. 2006: occluder-map texels scattered as micro-patches onto a soft shadow map. "
                   "Casters shadow receivers (Object → Penumbra → Shadow Role), an object itself too; "
                   "sphere lights use their bounding square")
    rim_views = True
    needs = (SSM_MAPS, SOFT_SHADOW_MAP, RECEIVER_MASK)    # with parameters from the options: needs_for
    options = (
        Option("ssm_map_size", 256, "Occluder Map Size",
               "Texels along the longer side of the occluder, receiver and soft shadow maps (the paper "
               "finds ~200 near optimal; cost grows with its square times the penumbra area)", 16, 2048),
        Option("ssm_texels", "SQUARE", "Texels", "Shape of the occluder-map texels", items=(
            ("SQUARE", "Square", "Square texels: a sliver light's maps as fine along both axes (default)"),
            ("LIGHT", "Light's Aspect (paper)", "Texels of the light's aspect ratio (§3.2): along a sliver "
                      "light's long side they are that many times longer, and so are the bias and the "
                      "shadow edges' steps"))),
        Option("ssm_passes", "TWO", "Passes", "Occluder maps scattered", items=(
            ("ONE", "One Pass", "Front-most occluder surfaces only"),
            ("TWO", "Two Passes", "Front-most and farthest back-facing occluder surfaces, merged by maximum "
                    "(§3.5)"))),
        Option("ssm_precision", "FLOAT32", "Accumulation", "Precision of the soft-shadow-map sums",
               items=PRECISION_ITEMS),
        Option("ssm_scatter", "RASTER", "Scatter", "How micro-patches are scattered", items=(
            ("RASTER", "Instanced Quads", "One quad per micro-patch, additive float blending (faster here)"),
            ("COMPUTE", "Compute + Atomics", "One invocation per micro-patch, fixed-point integer atomics"))),
        Option("ssm_weighting", "IRRADIANCE", "Weighting", "How a micro-patch's hidden part of the light counts",
               items=(("IRRADIANCE", "Irradiance", "Weighted by its share of the light's irradiance at the "
                       "receiver (rectangle form factor with the receiver's normal): closer to Cycles"),
                      ("UNIFORM", "Uniform (paper)", "Plain share of the light's area, as in the paper"))),
        Option("ssm_facets", True, "Sloped Facets",
               "Ours: each occluder texel spans its surface between depths shared with its neighbours, and counts "
               "negatively where a receiver sees it from behind, so the summed patches neither gap nor overlap "
               "(off: the paper's flat micro-patches, which over-darken penumbrae of curved casters)"),
        Option("ssm_refine", True, "Refine Hard Shadows",
               "Ours: a light whose penumbrae span under 4 texels of the occluder map (a point-like light) gets "
               "finer maps, up to the Shadow Map Size, so its hard shadow edges are no coarser than a hard shadow "
               "map's (off: Occluder Map Size for every light, as in the paper)"),
        Option("ssm_budget", 200.0, "Work Budget (M)",
               "Millions of soft-shadow-map texel updates allowed per occluder map; above it the maps are "
               "made coarser (the paper's remedy for large penumbrae, §5.1)", 1.0, 1.0e5),
    )
    debug_passes = (("SSM Occlusion", 1, "X", "VALUE"),)
    coarse = {"ssm_map_size": 64, "ssm_weighting": "UNIFORM"}
    sweep = ({"ssm_map_size": 64}, {"ssm_map_size": 128}, {"ssm_map_size": 256}, {"ssm_map_size": 512},
             {"ssm_weighting": "UNIFORM"})

    # ------------------------------------------------------------------------------------------------------
    def needs_for(self, s) -> tuple:
        return (need(SSM_MAPS, size=int(s.option("ssm_map_size")), budget=float(s.option("ssm_budget")) * 1e6,
                     two_pass=s.option("ssm_passes") == "TWO", light_aspect=s.option("ssm_texels") == "LIGHT",
                     facets=bool(s.option("ssm_facets")),
                     fine_size=int(s.shadow_map_size) if s.option("ssm_refine") else 0),
                need(SOFT_SHADOW_MAP, precision=s.option("ssm_precision"), method=s.option("ssm_scatter"),
                     weighted=s.option("ssm_weighting") == "IRRADIANCE"),
                RECEIVER_MASK)

    def visibility(self, frame, lc, out):
        s = frame.settings
        maps, soft = lc.structures[SSM_MAPS], lc.structures[SOFT_SHADOW_MAP]
        if soft is None:            # no caster can shadow a visible receiver (the maps say why)
            out.write(np.ones((frame.height, frame.width), np.float32).tobytes())
            return
        front, back, mask = soft.front, soft.back, lc.structures[RECEIVER_MASK]
        debug = frame.texture((frame.width, frame.height), 1) if s.debug_passes else out
        with frame.timings.stage("ssm_project"):
            frame.dispatch("ssm/project.comp", {
                **maps.view.uniforms(), **frame.bias_uniforms, "u_two_pass": int(back is not None),
                "u_debug": int(s.debug_passes), "u_has_mask": int(mask is not None)},
                samplers={"g_irradiance": lc.irradiance, "u_ssm_front": front,
                          "u_ssm_back": back if back is not None else front,
                          "u_recv_near": maps.maps["near"], "u_recv_far": maps.maps["far"],
                          "u_occluder": maps.maps["front"],
                          "u_receiver_mask": mask if mask is not None else maps.maps["near"]},
                images={0: out, 1: debug})
        if s.debug_passes:
            lc.debug["SSM Occlusion"] = frame.read(debug).copy()
