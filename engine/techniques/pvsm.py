"""PVSM: Shen, Guennebaud, Yang & Feng, "Predicted Virtual Soft Shadow Maps with High Quality Filtering"
(Eurographics 2011) — PCSS done right. Fixed-resolution mode (the paper's comparison mode, one map, no tiles);
per pixel, in glsl/pvsm/visibility.comp:

* z-averaging (§4 step 3): PCSS's blocker search on a low-resolution, min-reduced copy of the search map
  (and three coarser halvings for wide search boxes), keeping only cells that reach into the light–receiver
  pyramid at their own depth, each weighted by the share of the light it hides; no blocker → fully lit;
* the soft filter of Eq. 1, the light's shape scaled by α = (z_y − z_o)·z_n/(z_y·z_o), normalised by the
  kernel's actual area so that α → 0 (contact) and α → ∞ stay finite;
* smooth convolution (§4.1, Eq. 2): every texel a constant-depth quad weighted by its exact overlap with the
  kernel; a kernel wider than `pvsm_cap` texels reads every 2^l-th texel (as a map rendered 2^l times
  coarser would), so one loop visits at most about (cap + 2)² cells; texels of the receiver's own surface
  (close to it and outside their own light pyramid) are not counted; optional irradiance weighting of each
  texel's light sub-rectangle;
* anisotropic anti-aliasing (§4.2, Eq. 3): the pixel's axes through the receiver's tangent plane onto the
  map, convolved with the light filter as Gaussians and brought back to a parallelogram by Cholesky;
* perceptual resolution (§5.1, Eq. 4–5): the coarsest such level whose texels still give the kernel the
  ρ(n) texels a viewer needs at its screen size n.

Round lights (disk, ellipse, sphere, sun) use the box of equal variance (half extent √3/2 of the radius).
The tile grid and kd-tree of virtual tiles (§5.2 steps 4–7) are not built here.
"""
from __future__ import annotations

import math

import numpy as np

from ..core import lightview
from ..core.matrices import mat_uniform
from ..core.snapshot import SUN
from .backprojection import is_round, level_count
from .base import DEPTH_MAP, Option, Technique, light_shape_uniforms

# The map the blocker search reads. The paper renders it conservatively (§5.2 step 2) so that thin geometry is
# never lost and the fully-lit skip is safe; switch this one name to the conservative map structure when it
# exists (it must be an R32F linear light depth, NO_OCCLUDER where empty, like the depth map).
SEARCH_MAP = DEPTH_MAP
FILTER_MAP = DEPTH_MAP

RHO = {"NONE": 0, "DYNAMIC": 1, "STATIC": 2, "LINEAR": 3}
STATIC_PEAK = 7.6375     # where dρ_static/dx = 1.406 − 0.09374x − 0.011832x² = 0
ROUND_BOX = math.sqrt(3.0) / 2.0     # box of the same variance as a disk of radius 1


def rho(n, kind: str = "DYNAMIC"):
    """Texels a filter must span at a screen size of n pixels (§5.1, Eq. 4–5; x = log2 n held to [0, 9], and
    ρ_static's to its maximum at x ≈ 7.64, past which the fitted cubic turns down).
    The same formula as rho() in glsl/pvsm/visibility.comp, for the study and the tests."""
    x = np.clip(np.log2(np.maximum(np.asarray(n, float), 1e-6)), 0.0, 9.0)
    dyn = lambda t: 0.667 + 0.7794 * t + 0.3967 * t ** 2 - 0.02716 * t ** 3     # noqa: E731
    if kind == "STATIC":
        x = np.minimum(x, STATIC_PEAK)
        return 0.5477 + 1.406 * x - 0.04687 * x ** 2 - 0.003944 * x ** 3
    if kind == "LINEAR":
        return dyn(0.0) + (dyn(9.0) - dyn(0.0)) * x / 9.0
    return dyn(x)


def casters_inside(view, casters) -> bool:
    """True when the casters' bounds project inside the view's window: nothing past the map's edge can then
    occlude (the window is clipped at ±80° for a perspective view, or casters can surround the light)."""
    if casters is None:
        return True
    local = lightview.to_local(view.view, lightview.box_corners(*(np.asarray(c, float) for c in casters)))
    x0, x1, y0, y1 = view.window
    if view.is_ortho:
        w = local[:, :2]
    else:
        depth = -local[:, 2]
        if (depth <= 1e-9).any():
            return False
        w = local[:, :2] / depth[:, None]
    return bool((w[:, 0] >= x0).all() and (w[:, 0] <= x1).all() and (w[:, 1] >= y0).all() and (w[:, 1] <= y1).all())


class Pvsm(Technique):
    identifier = "PVSM"
    label = "PVSM (revisited PCSS)"
    description = ("Predicted virtual soft shadow maps (Shen et al. 2011), fixed-resolution mode: z-averaging "
                   "on a low-resolution map, exact box filtering of texels, analytic anisotropic anti-aliasing, "
                   "perceptual map resolution")
    needs = tuple(dict.fromkeys((SEARCH_MAP, FILTER_MAP)))
    options = (
        Option("pvsm_search_size", 256, "Search map", "Texels of the low-resolution level the blocker search "
               "(z-averaging) reads", min=16, max=4096),
        Option("pvsm_search_radius", 0.5, "Search radius", "Cap on the blocker search half extent, as a "
               "fraction of the map", min=0.001, max=1.0),
        Option("pvsm_cap", 24, "Kernel cap", "Most texels per axis one filter loop visits; wider kernels read "
               "a coarser level of the map", min=2, max=256),
        Option("pvsm_skip_lit", True, "Skip fully lit", "No blocker found → fully lit, no filtering (§5.2)"),
        # Off by default: against point-sampled references (Cycles' V per pixel, the stress oracle) it adds the
        # pixel's own blur, and across concave creases (room corners) its tangent-plane footprint reaches the
        # other wall, which then shadows the receiver (camera_in_box: 0.029 → 0.064 mae). It pays on sub-pixel
        # shadows (the study's thin bars: 0.28 → 0.08 against the box-filtered truth).
        Option("pvsm_antialiasing", False, "Anti-aliasing", "Convolve the kernel with the pixel's footprint "
               "on the map (§4.2)"),
        Option("pvsm_resolution", "NONE", "Resolution metric", "Which map level filters each pixel (§5.1)",
               items=(("NONE", "Finest", "The finest level under the kernel cap"),
                      ("DYNAMIC", "ρ dynamic", "The paper's metric for moving scenes (the conservative one)"),
                      ("STATIC", "ρ static", "The paper's metric for static scenes"),
                      ("LINEAR", "Linear", "A line in log2 n through ρ dynamic's end points (the paper's foil)"))),
        Option("pvsm_weighting", "IRRADIANCE", "Texel weights", "How a texel's share of the filter counts",
               items=(("IRRADIANCE", "Irradiance", "Each texel's light sub-rectangle weighted by the irradiance "
                       "it carries to a receiver facing the light (cosines over squared distance at its centre): "
                       "what Cycles measures"),
                      ("UNIFORM", "Uniform (paper)", "Plain area share of the texel, as in the paper"))),
    )
    coarse = {"pvsm_cap": 8}
    debug_passes = (("PVSM Level", 1, "X", "VALUE"),       # map level that filtered the pixel
                    ("PVSM Count", 1, "X", "VALUE"))       # cells visited (search + filter)
    sweep = tuple({"pvsm_cap": c} for c in (8, 16, 32, 64)) + (
        {"pvsm_resolution": "DYNAMIC"}, {"pvsm_resolution": "STATIC"}, {"pvsm_antialiasing": True},
        {"shadow_map_size": 512}, {"shadow_map_size": 2048})

    def visibility(self, frame, lc, out):
        s, light, view = frame.settings, lc.light, lc.view
        o = {opt.name: s.option(opt.name) for opt in self.options}
        w, h = view.width, view.height
        search = lc.structures[SEARCH_MAP]
        search_size = (search.width, search.height)
        # The low-resolution search map: min-reduced to about pvsm_search_size, and three levels that halve it
        # for search boxes wider than the cap (a light near its occluders).
        fine_block = max(1, 1 << max(0, int(math.ceil(math.log2(max(search_size) / int(o["pvsm_search_size"]))))))
        with frame.timings.stage("pvsm_search_map"):
            levels = [self._reduce(frame, search, search_size, fine_block)]
            for _ in range(3):
                levels.append(self._reduce(frame, levels[-1], (levels[-1].width, levels[-1].height), 2))
        shape = light_shape_uniforms(light, view)
        half = tuple(float(x) * (ROUND_BOX if is_round(light) else 1.0) for x in shape["u_light_half"])
        cam = frame.snap.camera
        info_wanted = bool(s.collect_stats or s.debug_passes)
        uniforms = {
            **lc.uniforms, "u_light_half": half,
            "u_search_scale": (search_size[0] / w, search_size[1] / h),
            "u_fine_block": fine_block,
            "u_filter_levels": level_count(w, h),
            "u_cap": int(o["pvsm_cap"]),
            "u_max_radius": float(o["pvsm_search_radius"]) * max(w, h),
            "u_skip_lit": int(bool(o["pvsm_skip_lit"])), "u_outside_lit": int(casters_inside(view, lc.casters)),
            "u_aa": int(bool(o["pvsm_antialiasing"])),
            "u_rho": RHO[o["pvsm_resolution"]],
            "u_inv_view_proj": mat_uniform(np.linalg.inv(cam.projection @ cam.view)),
        }
        # Irradiance weights need a light plane at a finite distance: not for suns or delta lights.
        defines = {"WEIGHTED": int(o["pvsm_weighting"] == "IRRADIANCE" and light.kind != SUN
                                   and not light.is_delta),
                   "INFO": int(info_wanted)}
        images = {0: out}
        info = None
        if info_wanted:
            info = images[1] = frame.texture((frame.width, frame.height), 4)
        frame.progress.check()
        with frame.timings.stage("pvsm_filter"):
            frame.dispatch("pvsm/visibility.comp", uniforms,
                           samplers={"g_irradiance": lc.irradiance,
                                     **{f"u_search{i}": t for i, t in enumerate(levels)},
                                     "u_depth_map": lc.structures[FILTER_MAP]},
                           images=images, defines=defines)
        if info is not None:
            self._gather(frame, lc, info)

    @staticmethod
    def _reduce(frame, src, size, block):
        """A map `block` times coarser, each texel the minimum depth of its block (glsl/pvsm/reduce.comp)."""
        out_size = (-(-size[0] // block), -(-size[1] // block))
        out = frame.texture(out_size, 1)
        frame.dispatch("pvsm/reduce.comp", {"u_src_size": tuple(size), "u_block": int(block)},
                       samplers={"u_src": src}, images={0: out}, size=out_size)
        return out

    def _gather(self, frame, lc, info):
        a = frame.read(info)
        cls, level, count = a[..., 0], a[..., 1], a[..., 3]
        reached = cls >= 0
        filtered = cls == 2
        lc.stats.update({"pixels": int(reached.sum()),
                         "share_skipped": float((cls == 0).sum() / max(reached.sum(), 1)),
                         "mean_level": float(level[filtered].mean()) if filtered.any() else 0.0,
                         "mean_count": float(count[filtered].mean()) if filtered.any() else 0.0})
        if frame.settings.debug_passes:
            lc.debug["PVSM Level"] = level[..., None].astype(np.float32)
            lc.debug["PVSM Count"] = count[..., None].astype(np.float32)
