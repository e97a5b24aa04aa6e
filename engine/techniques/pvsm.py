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

Adaptive mode (`pvsm_mode` ADAPTIVE, §5.2 steps 3–8): `shadow_map_size` is then the low-resolution map's, and
the filtering reads tiles of a virtual map finer or coarser than it by powers of two:
* step 3–4: one pass stores each pixel's blocker mean depth in a kernel shape buffer and min-blends the texel
  size its kernel needs into a 64² shadow map tile grid (see `splat` in the shader for the one change);
* step 5–6: the grid's pyramid and a kd-tree traversal after Giegl & Wimmer 2007 (`kd_tiles`): a node whose
  finest need fits `pvsm_tile_size` texels per axis is a leaf; otherwise it splits in halves along its
  longer side;
* step 7–8: each leaf a LightView of the light over its part of the window (`lightview.sub_view`), its depth
  map built by the depth-map structure builder, then filtering of every pixel whose kernel reaches it;
* the merge: each tile adds Σ V·A and Σ A over its part of the kernel, and V = Σ V·A / Σ A at the end.
"""
from __future__ import annotations

import math

import numpy as np

from dataclasses import replace

from ..core import lightview
from ..core.light_shape import is_round, weighted_sun_half
from ..core.matrices import mat_uniform
from ..core.shader_constants import PVSM_SEARCH_CELLS
from .. import structures
from ..gpu import loops
from ..structures.conservative_map import CONSERVATIVE_MAP
from .backprojection import level_count
from .base import DEPTH_MAP, Option, Technique, light_shape_uniforms

REDUCE_STEP = 16                # block side of one reduction pass (engine/gpu/loops.py: the loop limit)

# The map the blocker search reads, min-reduced to pvsm_search_size. The paper's is conservative (§5.2 step 2);
# CONSERVATIVE_MAP here renders one at pvsm_search_size, but measured at 128², 1024² map against Cycles it is
# no better anywhere and worse on `contact` (mae_shadow 0.031 → 0.040: the edge-on faces' conservative minimum
# is the top of the box, so blockers at the base look nearer the light and the contact shadow widens), so the
# hard depth map stays. Either is an R32F linear light depth, NO_OCCLUDER where empty.
SEARCH_MAP = DEPTH_MAP
FILTER_MAP = DEPTH_MAP

GRID = 64                   # cells per axis of the shadow map tile grid (§5.2 step 4)
EMPTY = -1000               # grid level of a cell no kernel reaches
UNBOUNDED = 1.0e30
RHO = {"NONE": 0, "DYNAMIC": 1, "STATIC": 2, "LINEAR": 3}
STATIC_PEAK = 7.6375     # where dρ_static/dx = 1.406 − 0.09374x − 0.011832x² = 0
ROUND_BOX = math.sqrt(3.0) / 2.0     # box of the same variance as a disk of radius 1
# A weighted sun's kernel stops at tan 4 (core.light_shape.SUN_KERNEL_TAN): a box out to tan 90° makes the
# filter read a level so coarse that the few cells carrying the weight miss the occluders (a ball under a 178°
# sun at 64², mae_shadow against Cycles: 0.095 unbounded, 0.065 at tan 8, 0.039 at tan 4 and tan 2).


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


def grid_shape(width: int, height: int, grid: int = GRID) -> tuple[int, int, int]:
    """(cell, cells along x, cells along y): square cells of a power-of-two number of low-resolution texels,
    at most `grid` of them per axis over a width × height map (the last row and column may reach past it)."""
    cell = 1 << max(0, int(math.ceil(math.log2(max(width, height) / grid))))
    return cell, -(-width // cell), -(-height // cell)


def level_range(cell: int, cells: int, tile_size: int, max_resolution: int,
                min_resolution: int = 0) -> tuple[int, int]:
    """Virtual map levels k (texels 2^−k low-resolution texels): no coarser than one texel per grid cell or
    than `min_resolution` texels across the grid (0: the low-resolution map itself), no finer than `max_resolution` texels across it or one cell
    per `tile_size`-texel tile."""
    k_min = -int(math.log2(cell))
    k_max = max(k_min, min(int(math.floor(math.log2(max_resolution / (cells * cell)))),
                           int(math.floor(math.log2(tile_size / cell)))))
    # By default no tile is coarser than the low-resolution map: a coarser map's texel-sized bias and normal
    # offset move the receiver (parallel planes: 0.005 → 0.010 mean error at 64² against 256²).
    floor = int(math.ceil(math.log2(min_resolution / (cells * cell)))) if min_resolution > 0 else 0
    return min(max(k_min, floor), k_max), k_max


def grid_levels(atlas: np.ndarray, size: int, k_range: tuple[int, int]) -> np.ndarray:
    """The level-0 grid of virtual levels from the shader's packed pyramid of texel sizes (rows: level 0's
    `size`, then level 1's size/2, …; +inf where nothing was splatted): every coarse cell's size pushed down to
    the cells under it, then k = ⌈−log2 r⌉ held to k_range; EMPTY where no kernel reached."""
    rows, levels, n = 0, [], size
    while n >= 1:
        levels.append(atlas[rows:rows + n, :n].astype(np.float64))
        rows += n
        n //= 2
    r = levels[-1]
    for finer in reversed(levels[:-1]):
        r = np.minimum(finer, np.kron(r, np.ones((2, 2))))
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.ceil(-np.log2(r))
    k = np.clip(np.nan_to_num(k, nan=k_range[1], posinf=k_range[1], neginf=k_range[0]), *k_range)
    return np.where(np.isfinite(r) & (r > 0), k, EMPTY).astype(np.int64)


def kd_tiles(need: np.ndarray, cell: int, tile_size: int, cells_x: int, cells_y: int) -> list[tuple]:
    """Giegl & Wimmer 2007's traversal: the tiles (i0, j0, i1, j1, k) in grid cells and virtual level.
    `need` is the (P, P) level-0 grid of levels (P a power of two); its max-pyramid answers each node's finest
    level. Nodes are power-of-two rectangles from the root down: a node that no kernel reaches is dropped, a
    node whose texels at its finest level fit `tile_size` per axis is a leaf, any other splits in halves along
    its longer side in texels. Leaves are clipped to the grid's cells_x × cells_y."""
    pyramid = [need]
    while pyramid[-1].shape[0] > 1:
        a = pyramid[-1]
        pyramid.append(np.maximum(np.maximum(a[0::2, 0::2], a[1::2, 0::2]), np.maximum(a[0::2, 1::2], a[1::2, 1::2])))
    size = need.shape[0]
    tiles, stack = [], [(0, 0, size, size)]
    while stack:
        i0, j0, i1, j1 = stack.pop()
        if i0 >= cells_x or j0 >= cells_y:
            continue
        m = int(math.log2(min(i1 - i0, j1 - j0)))
        k = int(pyramid[m][j0 >> m:j1 >> m, i0 >> m:i1 >> m].max())
        if k == EMPTY:
            continue
        ci1, cj1 = min(i1, cells_x), min(j1, cells_y)
        wide, high = ((ci1 - i0) * cell * 2.0 ** k, (cj1 - j0) * cell * 2.0 ** k)
        if (wide <= tile_size and high <= tile_size) or (i1 - i0 == 1 and j1 - j0 == 1):
            tiles.append((i0, j0, ci1, cj1, k))
        elif (i1 - i0) >= (j1 - j0):
            h = (i0 + i1) // 2
            stack += [(h, j0, i1, j1), (i0, j0, h, j1)]
        else:
            h = (j0 + j1) // 2
            stack += [(i0, h, i1, j1), (i0, j0, i1, h)]
    return tiles


class Pvsm(Technique):
    identifier = "PVSM"
    rim_views = True
    label = "PVSM (revisited PCSS)"
    description = ("Predicted virtual soft shadow maps (Shen et al. 2011): z-averaging on a low-resolution map, "
                   "exact box filtering of texels, analytic anisotropic anti-aliasing, perceptual map resolution, "
                   "one fixed map or adaptive tiles")
    needs = tuple(dict.fromkeys((SEARCH_MAP, FILTER_MAP)))
    options = (
        Option("pvsm_mode", "FIXED", "Mode", "One shadow map, or tiles of a virtual map at the resolution each "
               "region needs (§5.2)",
               items=(("FIXED", "Fixed", "One map at the shadow map size (the paper's comparison mode)"),
                      ("ADAPTIVE", "Adaptive tiles", "The shadow map size is the low-resolution map's; tiles of "
                       "a virtual map get the resolution their pixels' kernels need"))),
        Option("pvsm_tile_size", 4096, "Max tile", "Largest tile, texels per axis (adaptive mode)",
               min=4, max=16384),
        Option("pvsm_max_resolution", 16384, "Max resolution", "Finest virtual map, texels across the light "
               "view (adaptive mode)", min=16, max=262144),
        Option("pvsm_min_resolution", 0, "Min resolution", "Coarsest virtual map, texels across the light view "
               "(adaptive mode; 0: the shadow map size)", min=0, max=262144),
        Option("pvsm_search_size", 256, "Search map", "Texels of the low-resolution level the blocker search "
               "(z-averaging) reads", min=16, max=4096),
        Option("pvsm_search_radius", 0.5, "Search radius", "Cap on the blocker search half extent, as a "
               "fraction of the map", min=0.001, max=1.0),
        Option("pvsm_cap", 24, "Kernel cap", "Most texels per axis one filter loop visits; wider kernels read "
               "a coarser level of the map", min=2, max=256),
        Option("pvsm_cell_samples", 1, "Cell samples", "Depth tests per axis in each cell of a coarser level "
               "(1: the texel at its centre); more stop geometry finer than a cell from aliasing", min=1, max=8),
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
                       "it carries to a receiver facing the light (cosines over squared distance at its centre; "
                       "a sun's directions by solid angle and the receiver's cosine): what Cycles measures"),
                      ("UNIFORM", "Uniform (paper)", "Plain area share of the texel, as in the paper"))),
    )
    coarse = {"pvsm_cap": 8}
    debug_passes = (("PVSM Level", 1, "X", "VALUE"),       # map level that filtered the pixel
                    ("PVSM Count", 1, "X", "VALUE"))       # cells visited (search + filter)
    sweep = tuple({"pvsm_cap": c} for c in (8, 16, 32, 64)) + (
        {"pvsm_resolution": "DYNAMIC"}, {"pvsm_resolution": "STATIC"}, {"pvsm_antialiasing": True},
        {"shadow_map_size": 512}, {"shadow_map_size": 2048})

    def needs_for(self, settings) -> tuple:
        # The search map is rendered at the search size itself when it is the conservative one (§5.2 step 2).
        search = structures.need(SEARCH_MAP, size=int(settings.option("pvsm_search_size"))) \
            if SEARCH_MAP == CONSERVATIVE_MAP else SEARCH_MAP
        if settings.option("pvsm_mode") == "ADAPTIVE":
            return (search,)            # the tiles' maps are built per tile, in visibility()
        return (search, FILTER_MAP)

    def visibility(self, frame, lc, out):
        s, light, view = frame.settings, lc.light, lc.view
        o = {opt.name: s.option(opt.name) for opt in self.options}
        w, h = view.width, view.height
        search = getattr(lc.structures[SEARCH_MAP], "min_depth", lc.structures[SEARCH_MAP])
        search_size = (search.width, search.height)
        # The low-resolution search map: min-reduced to about pvsm_search_size, and three levels that halve it
        # for search boxes wider than the cap (a light near its occluders).
        fine_block = max(1, 1 << max(0, int(math.ceil(math.log2(max(search_size) / int(o["pvsm_search_size"]))))))
        # visibility.comp cuts a search box wider than PVSM_SEARCH_CELLS cells of its coarsest level (8 fine
        # blocks), keeping the search loop under llvmpipe's loop limit (engine/gpu/loops.py).
        reach = float(o["pvsm_search_radius"]) + (0.5 if o["pvsm_antialiasing"] else 0.0)   # AA: ≤ ½ map
        if min(2.0 * reach, 1.0) * max(search_size) > PVSM_SEARCH_CELLS * 8 * fine_block:
            frame.warn(f"PVSM: light '{light.name}': blocker search held to {PVSM_SEARCH_CELLS} cells per axis "
                       f"of its coarsest level (pvsm_search_radius × pvsm_search_size too large for the loop limit)")
        with frame.timings.stage("pvsm_search_map"):
            levels = [self._reduce(frame, search, search_size, fine_block)]
            for _ in range(3):
                levels.append(self._reduce(frame, levels[-1], (levels[-1].width, levels[-1].height), 2))
        shape = light_shape_uniforms(light, view)
        half = tuple(float(x) * (ROUND_BOX if is_round(light) else 1.0) for x in shape["u_light_half"])
        weighted = o["pvsm_weighting"] == "IRRADIANCE" and not light.is_delta
        if weighted:
            half = weighted_sun_half(light, half)
        cam = frame.snap.camera
        info_wanted = bool(s.collect_stats or s.debug_passes)
        uniforms = {
            # the light's own shape (a spot's cone clip reads it: visibility.comp set_light_part), and the
            # half extent of the box its kernels stand for it by
            **lc.uniforms, **shape, "u_kernel_half": half, "u_round_box": ROUND_BOX,
            "u_search_scale": (search_size[0] / w, search_size[1] / h),
            "u_fine_block": fine_block,
            "u_filter_levels": level_count(w, h),
            "u_cap": int(o["pvsm_cap"]), "u_sub": int(o["pvsm_cell_samples"]),
            "u_max_radius": float(o["pvsm_search_radius"]) * max(w, h),
            "u_skip_lit": int(bool(o["pvsm_skip_lit"])), "u_outside_lit": int(casters_inside(view, lc.casters)),
            "u_aa": int(bool(o["pvsm_antialiasing"])),
            "u_rho": RHO[o["pvsm_resolution"]],
            "u_inv_view_proj": mat_uniform(np.linalg.inv(cam.projection @ cam.view)),
            "u_clip": (-UNBOUNDED, -UNBOUNDED, UNBOUNDED, UNBOUNDED),
            "u_virtual_lo": (0.0, 0.0), "u_virtual_hi": (float(w), float(h)), "u_area_scale": 1.0,
        }
        # Irradiance weights: per light-plane position for a light at a finite distance, per direction for a
        # sun (visibility.comp); a delta light has no kernel to weight.
        defines = {"WEIGHTED": int(weighted), "SPOT_CLIP": int(shape["u_spot_cone"][0] > 0.0),
                   "INFO": int(info_wanted)}
        images = {0: out}
        info = None
        if info_wanted:
            info = images[1] = frame.texture((frame.width, frame.height), 4)
        frame.progress.check()
        samplers = {"g_irradiance": lc.irradiance, **{f"u_search{i}": t for i, t in enumerate(levels)}}
        if o["pvsm_mode"] == "ADAPTIVE":
            self._adaptive(frame, lc, out, uniforms, samplers, defines, info, o)
        else:
            with frame.timings.stage("pvsm_filter"):
                self._filter(frame, lc, uniforms, {**samplers, "u_depth_map": lc.structures[FILTER_MAP]}, images,
                             defines, o)
        if info is not None:
            self._gather(frame, lc, info)

    def _adaptive(self, frame, lc, out, uniforms, samplers, defines, info, o):
        """§5.2 steps 3–8 (see the module docstring)."""
        view, t = lc.view, frame.timings
        size = (frame.width, frame.height)
        cell, cells_x, cells_y = grid_shape(view.width, view.height)
        side = 1 << int(math.ceil(math.log2(max(cells_x, cells_y))))       # the pyramid's level-0 side
        with t.stage("pvsm_predict"):
            kernel, grid = frame.texture(size, 4), frame.texture((side, 2 * side), 1, dtype="u4")
            grid.write(np.full((2 * side, side), np.inf, np.float32).tobytes())
            frame.dispatch("pvsm/visibility.comp", {**uniforms, "u_grid_cell": float(cell), "u_grid_size": side},
                           samplers=samplers, images={0: kernel, 2: grid}, defines={**defines, "MODE": 1})
        with t.stage("pvsm_tiling"):
            atlas = np.frombuffer(grid.read(), np.float32).reshape(2 * side, side)
            k_range = level_range(cell, max(cells_x, cells_y), int(o["pvsm_tile_size"]),
                                  int(o["pvsm_max_resolution"]), int(o["pvsm_min_resolution"]))
            tiles = kd_tiles(grid_levels(atlas, side, k_range), cell, int(o["pvsm_tile_size"]), cells_x, cells_y)
        merge = frame.texture(size, 4)
        merge.write(np.zeros((frame.height, frame.width, 4), np.float32).tobytes())
        x0, x1, y0, y1 = view.window
        tx, ty = (x1 - x0) / view.width, (y1 - y0) / view.height        # window units per low-res texel
        texels = 0
        for index, (i0, j0, i1, j1, k) in enumerate(tiles):
            frame.progress.step(index / max(len(tiles), 1), f"{lc.light.name}: tile {index + 1}/{len(tiles)}")
            frame.progress.check()
            scale = cell * 2.0 ** k                                       # tile texels per grid cell
            tw, th = int(round((i1 - i0) * scale)), int(round((j1 - j0) * scale))
            tile = lightview.sub_view(view, (x0 + i0 * cell * tx, x0 + i1 * cell * tx,
                                             y0 + j0 * cell * ty, y0 + j1 * cell * ty), tw, th)
            tile_lc = replace(lc, view=tile, uniforms={**lc.uniforms, **tile.uniforms()}, structures={},
                              stats={}, debug={})
            with t.stage("pvsm_tile_maps"):
                depth = structures.build(FILTER_MAP, frame, tile_lc)
            texels += tw * th
            # The part of a kernel this tile owns: its rectangle, unbounded on the sides where it meets the
            # virtual map's edge (what lies past the edge is read at the edge, as one map reads it).
            ox, oy = i0 * scale, j0 * scale
            clip = (0.0 if i0 > 0 else -UNBOUNDED, 0.0 if j0 > 0 else -UNBOUNDED,
                    float(tw) if i1 < cells_x else UNBOUNDED, float(th) if j1 < cells_y else UNBOUNDED)
            vw, vh = cells_x * scale, cells_y * scale
            with t.stage("pvsm_filter"):
                self._filter(frame, lc,
                             {**uniforms, **tile_lc.uniforms, "u_clip": clip, "u_virtual_lo": (-ox, -oy),
                              "u_virtual_hi": (vw - ox, vh - oy), "u_area_scale": 4.0 ** -k,
                              "u_filter_levels": level_count(int(vw), int(vh))},
                             {"u_kernel": kernel, "u_depth_map": depth}, {0: merge}, {**defines, "MODE": 2}, o)
        with t.stage("pvsm_filter"):
            images = {0: out, **({1: info} if info is not None else {})}
            frame.dispatch("pvsm/visibility.comp", uniforms, samplers={"u_kernel": kernel, "u_merge": merge},
                           images=images, defines={**defines, "MODE": 3})
        frame.count(pvsm_tiles=len(tiles))
        lc.stats.update({"tiles": len(tiles), "tile_texels": texels,
                         "tile_levels": sorted({k for *_, k in tiles})})

    @staticmethod
    def _filter(frame, lc, uniforms, samplers, images, defines, o):
        """The filtering pass (MODE 0, or one tile's MODE 2), split over dispatches when a kernel can visit
        more depth tests than llvmpipe runs loop iterations (engine/gpu/loops.py): at most (cap + 2)² cells
        (cap_level), u_sub² tests each past level 0."""
        worst = (int(o["pvsm_cap"]) + 2) ** 2 * int(o["pvsm_cell_samples"]) ** 2
        chunks = loops.chunk_count(worst, loops.CHUNK)
        lc.stats["filter_dispatches"] = max(lc.stats.get("filter_dispatches", 0), chunks)
        if chunks == 1:
            frame.dispatch("pvsm/visibility.comp", uniforms, samplers=samplers, images=images, defines=defines)
            return
        if defines.get("MODE", 0) == 0:
            images = {**images, 3: frame.texture((frame.width, frame.height), 4)}
        for k in range(chunks):
            frame.progress.check()
            frame.dispatch("pvsm/visibility.comp", {**uniforms, **loops.chunk_uniforms(k, chunks, loops.CHUNK)},
                           samplers=samplers, images=images, defines={**defines, "CHUNKED": 1})

    @staticmethod
    def _reduce(frame, src, size, block):
        """A map `block` times coarser, each texel the minimum depth of its block (glsl/pvsm/reduce.comp), in
        steps of at most REDUCE_STEP² texels (a 4096² map to a 16² search map, 256² per texel in one step, passes
        llvmpipe's loop limit; a min of mins is the same min)."""
        while block > 1:
            step = min(block, REDUCE_STEP)
            out_size = (-(-size[0] // step), -(-size[1] // step))
            out = frame.texture(out_size, 1)
            frame.dispatch("pvsm/reduce.comp", {"u_src_size": tuple(size), "u_block": int(step)},
                           samplers={"u_src": src}, images={0: out}, size=out_size)
            src, size, block = out, out_size, -(-block // step)
        return src

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
