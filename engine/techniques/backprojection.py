"""BACKPROJECTION: soft shadows by backprojecting depth-map micro-occluders onto the light.

Schwarz & Stamminger, "Bitmask Soft Shadows" (2007), with its baseline Guennebaud, Barthe & Paulin, "Real-time
soft shadow mapping by backprojection" (GBP06) as one setting (micropatches + gap filling, area accumulation,
HSM). Per pixel, in glsl/backprojection/visibility.comp:

* search area = receiver–light pyramid ∩ the depth map's near plane (§2.1), refined with a min/max hierarchy
  (HSM, GBP06) or the multi-scale shadow map (MSSM, §5); pixels proven fully lit or in umbra stop there;
* every texel in the area is a micro-occluder: a micropatch (GBP06, with gap filling towards the left/bottom
  neighbours) or a microquad (§4, texel centres as vertices), unprojected and backprojected onto the light;
* occlusion is accumulated as an area (GBP06, clamped to 1) or OR-ed into an N×N occlusion bitmask of light
  samples (§3: 8×8, 16×16, 16×16 jittered = 8×8 tiling of the 2×2 RGSS pattern, 32×32); V = unset / all;
* at most b×b micro-occluders per layer: a coarser hierarchy level, sampled on its own grid, when the area is
  larger (§5);
* by default (bp_coarse_fit, ours; NONE is the papers') a coarse micropatch/microrect refitted per receiver
  to its finer-level parts that occlude it: their bounding box, at their mean depth (or minimum), tilted by
  their depth slope (PLANE, the default), instead of the whole cell at the minimum depth of all its texels
  (which over-darkens beside silhouettes and under surfaces the light grazes, and next to a contact covers the
  wrong share of the light); with any refit, a receiver the depth map sees keeps the light's centre out of
  every coarse micro-occluder's light rectangle; and (bp_coverage, ours) shrunk to the share of its texels
  nearer than the receiver, from
  the count, mean, maximum and variance of their depths (structures/coverage.py, the microrects' members), so
  that bars finer than a coarse cell with gaps between them do not fuse into an umbra; and (bp_split, ours)
  split into its finer parts, down to level 0, while it backprojects wider than a share of the light (next to
  contacts), as is a coarse cell whose nearest texel lies on the receiver's own plane while its mean depth is
  nearer than that plane (a floor in front of a post's foot hiding the foot from the cell's test);
* (bp_solid_columns, ours) where the depth map's surface is a closed caster's front face, the micro-occluder
  reaches through the solid to the light centre's exit from it (structures/solid_exits.py), its
  backprojection the rectangle swept from its near end to its far end: the light's other points see the
  solid's sides, which the depth map holds no texel of;
* post-filtering of the bitmask visibility driven by the area values (§3.1, glsl/backprojection/filter.comp);
* depth peeling from the light centre, 1–4 layers (§3.2), all OR-ed into the same bitmask;
* round lights (disk, ellipse, point/spot radius, sun) through the sample mask; textured lights (§3.3) through
  per-sample colours when the snapshot's Light carries a `texture` (see `light_texture`).

Light kinds: AREA (all shapes) exactly; POINT/SPOT with a radius as a disk of that radius facing the map's
axis; SUN with its orthographic map: micro-occluders backproject to directions (offset per unit depth); delta
lights (no extent) fall back to a hard shadow-map test.

The depth map, peeled layers, HSM pyramids, MSSM and solid exits are per-light structures (engine/structures/),
declared by `needs_for` from the options; this module runs the gather and the post-filter.
"""
from __future__ import annotations

import numpy as np

from ..core import importance
from ..core.light_shape import is_round, weighted_sun_half
from ..core.shader_constants import (BUDGET_BORDER, BUDGET_IMPORTANCE, BUDGET_UNBOUNDED, BUDGET_UNIFORM,
                                     CLASS_BACKPROJECTED, CLASS_LIT, CLASS_UMBRA, LOQ_BLEND, LOQ_INTEGER, LOQ_WRITE,
                                     PRIMITIVE_MICROPATCH, PRIMITIVE_MICROQUAD, PRIMITIVE_MICRORECT, REFINE_HSM,
                                     REFINE_MSSM, REFINE_NONE, REFINE_YSM, REFIT_DEPTH, REFIT_EXTENT, REFIT_MEAN, REFIT_PLANE,
                                     REFIT_CORNERS, REFIT_NONE, REFIT_PARTS_MICROPATCH, REFIT_PARTS_MICRORECT)
from ..gpu import loops
from ..structures import need
from ..structures.coverage import COVERAGE
from ..structures.hsm import HSM
from ..structures.microrects import MICRORECTS
from ..structures.mssm import MSSM, level_count
from ..structures.peeled_layers import PEELED_LAYERS
from ..structures.solid_exits import SOLID_EXITS
from ..structures.ysm import YSM
from .base import DEPTH_MAP, Option, Technique, light_shape_uniforms

PRIMITIVES = (("MICROPATCH", "Micropatches", "Each texel a square parallel to the light (GBP06)"),
              ("MICROQUAD", "Microquads", "Texel centres as quad vertices (Schwarz & Stamminger §4)"),
              ("MICRORECT", "Microrects", "Micropatches whose coarse-level extents follow the occluders, by a "
               "greedy merge (Schwarz & Stamminger 2008, §5.2); level 0 equals micropatches"))
ACCUMULATIONS = (
    ("AREA", "Area accumulation", "Sum of the backprojected areas, clamped to 1 (GBP06): overlaps count twice"),
    ("BITMASK_8", "Bitmask 8×8", "Occlusion bitmask, regular 8×8 light samples"),
    ("BITMASK_16", "Bitmask 16×16", "Occlusion bitmask, regular 16×16 light samples"),
    ("BITMASK_16J", "Bitmask 16×16 jittered", "Occlusion bitmask, 8×8 tiling of the 2×2 rotated grid"),
    ("BITMASK_32", "Bitmask 32×32", "Occlusion bitmask, regular 32×32 light samples"),
    ("BITMASK_16MJ", "Bitmask 16×16 multi-jittered", "Occlusion bitmask, 16×16 samples each with its own column "
     "and row offset (multi-jittered rooks): an edge along the light's sides steps in 1/256, not 1/32 (ours)"),
    ("BITMASK_32MJ", "Bitmask 32×32 multi-jittered", "The same for 32×32 samples: steps of 1/1024 (ours)"),
)
REFINEMENTS = (("NONE", "None", "Search the whole pyramid ∩ near plane; no lit/umbra classification"),
               ("HSM", "HSM", "Min/max mip pyramid (GBP06)"),
               ("MSSM", "MSSM", "Multi-scale shadow map: full resolution at every level (§5)"),
               ("YSM", "YSM", "Y shadow map: the HSM's first levels plus a 256² MSSM built from the HSM "
                "(Schwarz & Stamminger 2008, §6)"))
BUDGET_MAPS = (("UNIFORM", "Uniform", "The same budget b at every pixel"),
               ("BORDER", "Border falloff", "b at the image centre falling linearly to the border budget at the "
                "left and right borders (Schwarz & Stamminger 2008, Fig. 1d)"),
               ("UNBOUNDED", "Unbounded (b = ∞)", "Level 0 always, no blending: the paper's baseline"),
               ("IMPORTANCE", "Importance", "From the low budget (importance 0) to b (importance 1), the "
                "importance being the budget image's grey value or the importance of the object seen at the "
                "pixel, the larger (Schwarz & Stamminger 2008, §4.2)"))
BUDGET_MODE = {"UNIFORM": BUDGET_UNIFORM, "BORDER": BUDGET_BORDER, "UNBOUNDED": BUDGET_UNBOUNDED,
               "IMPORTANCE": BUDGET_IMPORTANCE}
PRIMITIVE = {"MICROPATCH": PRIMITIVE_MICROPATCH, "MICROQUAD": PRIMITIVE_MICROQUAD, "MICRORECT": PRIMITIVE_MICRORECT}

BITS = {"AREA": 0, "BITMASK_8": 8, "BITMASK_16": 16, "BITMASK_16J": 16, "BITMASK_32": 32, "BITMASK_16MJ": 16,
        "BITMASK_32MJ": 32}
MULTI_JITTERED = ("BITMASK_16MJ", "BITMASK_32MJ")       # visibility.comp MULTI_JITTER
REFINE = {"NONE": REFINE_NONE, "HSM": REFINE_HSM, "MSSM": REFINE_MSSM, "YSM": REFINE_YSM}
REFIT = {"NONE": REFIT_NONE, "EXTENT": REFIT_EXTENT, "MEAN": REFIT_MEAN, "DEPTH": REFIT_DEPTH, "PLANE": REFIT_PLANE}
LOQ_DEPTH_JUMP = 0.05           # relative camera-depth jump at which the LOQ smoothing stops (a discontinuity)

# Mesa's llvmpipe ends a shader's loops once they have run 65535 iterations in all (engine/gpu/loops.py,
# shared by every loop of an invocation): a gather over more micro-occluders stopped part-way, and every loop
# after it ran once (the bitmask count saw one row: black). That was b = ∞ on big_light (~573k per pixel). One
# dispatch gathers at most CHUNK_CELLS per pixel; a SIMD group may run two gathers' shares back to back
# (blending), so twice this plus the classification's and resolve's short loops stays below the limit.
CHUNK_CELLS = 16384


def sample_pattern(accumulation: str) -> tuple[int, tuple, tuple]:
    """(N, jitter_x per row parity, jitter_y per column parity): sample (column k, row l) of the N×N bitmask
    sits at ((k + jx[l & 1]) / N, (l + jy[k & 1]) / N) in [0, 1]² over the light's bounding rectangle.

    §3: the jittered 16×16 pattern is an 8×8 tiling of the 2×2 rotated-grid (RGSS) cell whose samples are
    (3/8, 1/8), (7/8, 3/8), (1/8, 5/8), (5/8, 7/8) of the cell: in units of the 16×16 grid that is
    x = k + (¾ on even rows, ¼ on odd rows), y = l + (¼ on even columns, ¾ on odd columns)."""
    n = BITS[accumulation]
    if accumulation in MULTI_JITTERED:          # per sample, not per parity: sample_positions
        return n, (0.5, 0.5), (0.5, 0.5)
    if accumulation == "BITMASK_16J":
        return n, (0.75, 0.25), (0.25, 0.75)
    return n, (0.5, 0.5), (0.5, 0.5)


def sample_positions(accumulation: str) -> np.ndarray:
    """(N, N, 2) sample positions in [0, 1]², indexed [row l, column k]. The multi-jittered pattern puts sample
    (k, l) at ((k + (P[l] + ½)/N) / N, (l + (P[k] + ½)/N) / N), P the bit-reversal permutation."""
    n, jx, jy = sample_pattern(accumulation)
    k = np.arange(n)[None, :]
    l_ = np.arange(n)[:, None]
    if accumulation in MULTI_JITTERED:
        p = bit_reversal(n)
        x = (k + (p[l_] + 0.5) / n) / n
        y = (l_ + (p[k] + 0.5) / n) / n
    else:
        x = (k + np.array(jx)[l_ & 1]) / n
        y = (l_ + np.array(jy)[k & 1]) / n
    return np.stack(np.broadcast_arrays(x, y), axis=-1)


def bit_reversal(n: int) -> np.ndarray:
    """The bit-reversal permutation of 0 … n − 1 (n a power of two): the multi-jittered pattern's offsets."""
    bits = max(n - 1, 0).bit_length()
    return np.array([int(format(i, f"0{bits}b")[::-1], 2) for i in range(n)])


def multi_jitter_defines(n: int) -> dict:
    """visibility.comp's multi-jittered tables as GLSL array literals: MJ_PERM (P) and MJ_AT_LEAST[t], the
    bitmask of the columns k with P[k] ≥ t, for t = 0 … n."""
    p = bit_reversal(n)
    at_least = [sum(1 << k for k in range(n) if p[k] >= t) for t in range(n + 1)]
    return {"MJ_PERM_VALUES": f"int[{n}](" + ", ".join(str(int(v)) for v in p) + ")",
            "MJ_AT_LEAST_VALUES": f"uint[{n + 1}](" + ", ".join(f"0x{m:x}u" for m in at_least) + ")"}


def valid_mask(accumulation: str, round_: bool) -> np.ndarray:
    """(N, N) bool: samples inside the light's shape (the inscribed ellipse for round lights)."""
    pos = sample_positions(accumulation)
    if not round_:
        return np.ones(pos.shape[:2], bool)
    q = pos * 2.0 - 1.0
    return (q ** 2).sum(-1) <= 1.0


def light_texture(light):
    """The light's emission texture, or None: (H, W, 3) float linear RGB over the light's local [-1, 1]²
    (row 0 at local y = −1, column 0 at x = −1), as `Light.texture` (a proposed snapshot field)."""
    tex = getattr(light, "texture", None)
    if tex is None:
        return None
    tex = np.asarray(tex, np.float32)
    if tex.ndim != 3 or tex.shape[2] < 3 or tex.shape[0] < 1 or tex.shape[1] < 1:
        return None
    return np.nan_to_num(np.clip(tex[..., :3], 0.0, None))


def sample_colors(texture: np.ndarray, accumulation: str) -> np.ndarray:
    """(N, N, 3): the texture bilinearly sampled at each bitmask sample (§3.3)."""
    pos = sample_positions(accumulation)
    h, w = texture.shape[:2]
    return importance.bilinear(texture, pos[..., 0] * w - 0.5, pos[..., 1] * h - 0.5)


def luminance(rgb) -> np.ndarray:
    return np.asarray(rgb, np.float64) @ np.array([0.2126, 0.7152, 0.0722])


def gather_cells_bound(map_size, layers: int, quad_extra: int, budget_mode: int, force_level: int,
                       budget_max: float, blend: bool, levels: int) -> int:
    """Most micro-occluders one pixel's gathers can visit (visibility.comp gather_cells, all layers, both
    levels when blending): the search area is clamped to the map, and a budget b keeps the integer level's
    area within b cells per side; a blended ⌊ℓ⌋ may be up to two levels finer than that (the smoothed ℓ falls
    at most one below the pixel's own), ⌈ℓ⌉ one."""
    def cells(level, per_side=None):
        n = [((s - 1) >> level) + 1 + quad_extra for s in map_size]
        if per_side is not None:
            n = [min(v, per_side) for v in n]
        return n[0] * n[1]
    if force_level >= 0:
        return layers * cells(min(force_level, levels - 1))
    if budget_mode == BUDGET_UNBOUNDED:
        return layers * cells(0)
    b = int(np.ceil(budget_max))
    if not blend:
        return layers * cells(0, b)
    return layers * (cells(0, 4 * b + 2 + quad_extra) + cells(min(1, levels - 1), 2 * b + 2 + quad_extra))


# The loop iterations of visibility.comp's coarse refit over a micro-occluder's finer parts (refit).
REFIT_PARTS = {PRIMITIVE_MICRORECT: REFIT_PARTS_MICRORECT, PRIMITIVE_MICROPATCH: REFIT_PARTS_MICROPATCH}


def refit_iterations(defines: dict) -> int:
    """Loop iterations the coarse refit costs one coarse micro-occluder: its loop over the finer parts and
    (REFIT_PLANE) backproject_tilted's over the corners. visibility.comp gets it as REFIT_ITERATIONS, for the
    split's parts (part_iterations)."""
    if defines["REFIT"] == REFIT_NONE:
        return 0
    return REFIT_PARTS.get(defines["PRIMITIVE"], 0) + (REFIT_CORNERS if defines["REFIT"] == REFIT_PLANE else 0)


def cell_iterations(defines: dict, coarse: bool) -> int:
    """Loop iterations one micro-occluder may cost a gather, all of which llvmpipe's limit counts (CHUNK_CELLS):
    its own; the near-field split's two loops, which run for every micro-occluder even where they split
    nothing (with b = ∞ the split's mere presence changed the visibility); and where levels above 0 can be
    gathered (`coarse`), the coarse refit's (refit_iterations). Counting the cells and the split alone let a
    forced level 1 run past the limit: the refit found no part, every coarse microrect was dropped and the
    umbra leaked (tilted at 128², level 1: mae_shadow 0.17, 0.0066 counted). Unrolling the refit instead
    made every frame slower on llvmpipe (tilted 1.6 → 2.9 s) than the extra dispatches (1.6 → 1.7 s)."""
    return 1 + (2 if defines["SPLIT"] else 0) + (refit_iterations(defines) if coarse else 0)


def budget_max_of(o) -> float:
    """The largest budget b_mo the budget map gives any pixel."""
    mode = o["bp_budget_map"]
    return max(float(o["bp_budget"]), float(o["bp_budget_border"]) if mode == "BORDER"
               else float(o["bp_budget_low"]) if mode == "IMPORTANCE" else 0.0)


# Loop iterations the near-field split (bp_split) may add per pixel and gather (per dispatch when chunked),
# each finer part costing its own and its refit's (visibility.comp part_iterations): next to a contact cells
# split down to level 0, whatever the budget. The cap keeps llvmpipe's loop counter (one per SIMD group of
# 8 lanes that run a loop together, engine/gpu/loops.py) below its limit: a dispatch's two gathers of
# CHUNK_CELLS iterations each plus their parts', 2·(16384 + 8192) = 49152 < 65535. A cap of 1024 parts,
# counted alone, let parts of level 1 and above pass it (bp_split 0.1 on tilted at 128²: light streaks).
SPLIT_EXTRA = 8192


def _mask_rows(valid: np.ndarray) -> list[int]:
    rows = [0] * len(valid)
    for l_, row in enumerate(valid):
        rows[l_] = int(sum(1 << k for k, on in enumerate(row) if on))
    return rows


# ------------------------------------------------------------------------------------------------------------
# the technique
# ------------------------------------------------------------------------------------------------------------

class Backprojection(Technique):
    identifier = "BACKPROJECTION"
    label = "Backprojection (bitmask soft shadows)"
    description = ("Depth-map texels backprojected onto the light (Schwarz & Stamminger 2007, GBP06): occlusion "
                   "bitmasks with correct occluder fusion, microquads, HSM/MSSM search-area refinement, depth "
                   "peeling. Area lights of every shape, point/spot radius as a disk, sun as a disk of "
                   "directions; textured lights through per-sample colours")
    rim_views = True
    needs = (DEPTH_MAP, PEELED_LAYERS, HSM, MSSM, YSM, MICRORECTS, COVERAGE, SOLID_EXITS)  # all it may use
    options = (
        Option("bp_primitive", "MICRORECT", "Micro-occluders", "How depth-map texels become occluders",
               items=PRIMITIVES),
        Option("bp_gap_fill", True, "Gap filling",
               "Micropatches: extend each patch to its left/bottom occluding neighbour (GBP06)"),
        # BITMASK_32MJ, not the paper's 16J. At 128² against Cycles 1024 spp (`python -m penumbra bench
        # --techniques BACKPROJECTION --peers none --repeats 1 --set bp_accumulation=...`), 16J → 16MJ → 32MJ:
        # plane and textured 0.0058 → 0.0019 → 0.0011, silhouette 0.0066 → 0.0039 → 0.0028, grazing 0.0097 →
        # 0.0069 → 0.0046, cube 0.0064 → 0.0061 → 0.0034, thin 0.0320 → 0.0306 → 0.0269, slab 0.0108 → 0.0114
        # → 0.0093, room 0.0061 → 0.0055 → 0.0050, tilted 0.0112 → 0.0107 → 0.0108, balls 0.0162 → 0.0164 →
        # 0.0157, the other four within 2 % or better; the 14 summed 0.1842 → 0.1686 → 0.1526, every scene better
        # with 32MJ than with 16J. Frame time summed on llvmpipe 43.3 → 47.1 → 63.9 s (twice the rows per
        # micro-occluder): the viewport's coarse frames keep 16MJ. A sheared lattice (the offsets in plain
        # order) instead of 16MJ: 0.1879.
        Option("bp_accumulation", "BITMASK_32MJ", "Occlusion", "How backprojected occlusion is combined",
               items=ACCUMULATIONS),
        Option("bp_refinement", "YSM", "Search refinement",
               "Narrow the search area and classify fully lit / umbra pixels (§5)", items=REFINEMENTS),
        Option("bp_budget", 16, "Budget", "At most b×b micro-occluders per pixel and depth layer; larger search "
               "areas use a coarser level (with a border falloff: b at the image centre)", min=2, max=64),
        Option("bp_budget_map", "UNIFORM", "Budget map", "How the budget b_mo varies over the image (§4.2 of "
               "the 2008 paper)", items=BUDGET_MAPS),
        Option("bp_budget_border", 5, "Border budget", "Budget at the left/right image borders (border falloff)",
               min=2, max=64),
        Option("bp_budget_low", 5, "Low budget", "Importance budget map: the budget where the importance is 0",
               min=2, max=64),
        Option("bp_budget_image", "", "Budget image", "Importance budget map: a Blender image (by name) or an "
               "image file whose grey value (0 … 1, stretched over the frame) is each pixel's importance; "
               "empty: only the objects' Shadow Importance"),
        Option("bp_blend", True, "Level blending", "Fractional level from area and budget, smoothed in an LOQ "
               "map (11×11 bilateral, stops at depth discontinuities), visibility of the two nearest levels "
               "blended (Schwarz & Stamminger 2008, §4.2); off: one integer level per pixel (2007)"),
        Option("bp_query_growth", True, "Over-precision fix", "Grow the queried area to the support of the "
               "micro-occluders of the level it will use before classifying (2008, §6)"),
        Option("bp_coarse_fit", "PLANE", "Coarse refit", "Coarse micro-occluders (micropatches, microrects) "
               "fitted per receiver to their finer-level cells that occlude it, and kept off the light's centre "
               "where the depth map sees the receiver (not in the papers)",
               items=(("NONE", "None (papers)", "The cell or microrect at the minimum depth of all its texels"),
                      ("EXTENT", "Extent", "Shrunk to the occluding finer cells, at their minimum depth"),
                      ("MEAN", "Extent and mean depth", "Shrunk to the occluding finer cells, at their mean "
                       "depth"),
                      ("DEPTH", "Mean depth", "Its own extent, at the mean depth of its occluding finer cells"),
                      ("PLANE", "Extent, mean depth and slope", "As MEAN, tilted by the depth slope of its occluding "
                       "finer cells: a surface the light grazes stays on that surface next to the receiver"))),
        Option("bp_coverage", True, "Coarse coverage", "Coarse micro-occluders (micropatches, microrects) "
               "shrunk to the share of their texels nearer than the receiver, from their depth statistics: "
               "occluders finer than a cell (grids, fences) stop fusing into an umbra (not in the papers)"),
        # 0.3 → 0.2 (128², Cycles 1024 spp, once split parts counted their loop iterations): better or equal on
        # all 14 built-in scenes (tilted 0.0232 → 0.0198, slab 0.0215 → 0.0183, suzanne 0.0235 → 0.0201) for
        # 6 % more frame time in all. 0.2 → 0.15, with the coverage shrink towards the occluding parts: contact
        # 0.0171 → 0.0126, slab 0.0183 → 0.0165, suzanne 0.0200 → 0.0189, balls 0.0201 → 0.0189, tilted 0.0196 →
        # 0.0186, no scene worse by more than 1.1 %, for 20 % more frame time over the 14.
        Option("bp_split", 0.15, "Near-field split", "Coarse micro-occluders (micropatches, microrects) whose "
               "backprojection is wider than this share of the light's side are replaced by their finer parts, "
               "down to level 0: next to the receiver (contact shadows, a surface beside it) one coarse cell "
               "spans much of the light and its error becomes the penumbra's (tilted at 128²: mae_shadow 0.029 "
               "with 0, 0.019 with 0.15). With coarse coverage on, a cell whose nearest texel lies on the "
               "receiver's plane but whose mean depth is nearer than it splits too (grazing at 128²: 0.019 → "
               "0.015). 0: off, the papers (not in them)",
               min=0.0, max=4.0),
        # On (128², Cycles 1024 spp): grazing 0.0145 → 0.0097, tilted 0.0142 → 0.0112, room 0.0115 → 0.0061,
        # contact 0.0123 → 0.0120, balls 0.0161 → 0.0166, thin +0.7 %, the other eight within 0.5 %; 1.38× the
        # frame time summed over the 14 on llvmpipe. The columns stand for a closed caster's far side, so the
        # peeling then leaves it out (bp_layers): layer 1 holds only what the near side hides, and where nothing
        # is hidden it comes out empty and is dropped (grazing, cube, tilted, room, slab: half the frame time);
        # against the columns with the far side peeled: contact 0.0120 → 0.0112, balls 0.0166 → 0.0162, cube
        # 0.0066 → 0.0064, thin 0.0326 → 0.0320, slab 0.0105 → 0.0108, the rest within 0.3 %; frame time summed
        # 47.5 → 42.4 s (without columns 35.6 s).
        Option("bp_solid_columns", True, "Solid columns", "Micro-occluders of closed objects reach through the "
               "solid to where the light centre's ray leaves it, so the light's other points see the object's "
               "sides, which the depth map holds no texel of (a post under a low light); off: the papers' "
               "surface micro-occluders (not in them)"),
        Option("bp_force_level", -1, "Forced level", "−1: from the budget; ≥ 0: every pixel gathers at this "
               "hierarchy level (for studies of coarse-level occluder approximations)", min=-1, max=16),
        Option("bp_filter_passes", 0, "Filter passes",
               "Post-filter passes of the bitmask visibility driven by the area values (§3.1)", min=0, max=16),
        Option("bp_layers", 2, "Depth layers", "Depth-peeled layers from the light centre (§3.2): occluders the "
               "centre cannot see (a plate under a wider one) still shadow. Of a closed object only faces the "
               "light can see on its outline are peeled (none with Solid columns, which stand for its far side), "
               "and a layer with nothing behind it is left out",
               min=1, max=4),
        Option("bp_weighting", "IRRADIANCE", "Sample weights", "How the bitmask's light samples are counted",
               items=(("IRRADIANCE", "Irradiance", "Each light sample weighted by its unoccluded contribution "
                       "at the receiver (cosines over squared distance): the visibility Cycles measures"),
                      ("UNIFORM", "Uniform (paper)", "Plain share of the light's samples, as in the paper"))),
    )
    coarse = {"bp_budget": 8, "bp_accumulation": "BITMASK_16MJ"}
    debug_passes = (
        ("BP Class", 3, "RGB", "COLOR"),            # green: proven lit, red: umbra, blue: backprojected
        ("BP Level", 1, "X", "VALUE"),              # hierarchy level the micro-occluders came from
        ("BP Count", 1, "X", "VALUE"),              # micro-occluders processed (all layers)
        ("BP Color Visibility", 3, "RGB", "COLOR"),  # per-channel visibility of a textured light (§3.3)
    )
    sweep = tuple(
        [{"bp_accumulation": a, "bp_primitive": p, "bp_refinement": r}
         for r in ("HSM", "MSSM")
         for a, p in (("AREA", "MICROPATCH"), ("AREA", "MICROQUAD"), ("BITMASK_8", "MICROPATCH"),
                      ("BITMASK_16", "MICROPATCH"), ("BITMASK_16J", "MICROPATCH"), ("BITMASK_32", "MICROPATCH"),
                      ("BITMASK_16J", "MICROQUAD"))]
        + [{"bp_refinement": "NONE"}, {"bp_layers": 1}, {"bp_filter_passes": 5}, {"bp_budget": 8},
           {"bp_budget": 32}, {"bp_gap_fill": False}, {"shadow_map_size": 512}, {"shadow_map_size": 2048}]
        # Schwarz & Stamminger 2008: budget maps, blending, over-precision fix, microrects, YSM.
        + [{"bp_budget_map": "UNBOUNDED"}, {"bp_budget_map": "BORDER", "bp_budget": 12, "bp_budget_border": 5},
           {"bp_blend": True}, {"bp_query_growth": True}, {"bp_primitive": "MICRORECT"},
           {"bp_refinement": "YSM"},
           {"bp_primitive": "MICRORECT", "bp_refinement": "YSM", "bp_blend": True, "bp_query_growth": True}]
        # Ours: coarse micro-occluders refitted to their occluding finer parts (PLANE, the default), and the
        # papers' whole cell at its minimum depth; the coverage shrink off; the near-field split finer or off.
        + [{"bp_coarse_fit": "NONE"}, {"bp_coarse_fit": "EXTENT"}, {"bp_coarse_fit": "MEAN"},
           {"bp_coarse_fit": "DEPTH"}, {"bp_coverage": False}, {"bp_split": 0.2}, {"bp_split": 0.0}])

    def settings_of(self, s) -> dict:
        return {o.name: s.option(o.name) for o in self.options}

    def needs_for(self, s) -> tuple:
        """Depth map, its peeled layers (§3.2), their min/max pyramids and, for MSSM refinement, the
        multi-scale shadow map of layer 0 (§5), which then stands in for layer 0's pyramid."""
        o = self.settings_of(s)
        mssm, ysm = o["bp_refinement"] == "MSSM", o["bp_refinement"] == "YSM"
        hsm = need(HSM, mssm_first=mssm, ysm_first=True) if ysm else need(HSM, mssm_first=mssm)
        return (DEPTH_MAP, *((SOLID_EXITS,) if self._columns(o) else ()),
                need(PEELED_LAYERS, layers=int(o["bp_layers"]), far_side=not self._columns(o)), hsm,
                *((MSSM,) if mssm else ()), *((YSM,) if ysm else ()),
                *((need(MICRORECTS, stats=True) if self._coverage(o) else MICRORECTS,)
                  if o["bp_primitive"] == "MICRORECT" else ()),
                *((COVERAGE,) if self._coverage(o) and o["bp_primitive"] == "MICROPATCH" else ()))

    @staticmethod
    def _split(o) -> float:
        """The near-field split's threshold, 0 where it does not apply (microquads have no finer parts)."""
        return 0.0 if o["bp_primitive"] == "MICROQUAD" else float(o["bp_split"])

    @staticmethod
    def _columns(o) -> bool:
        """Solid columns for closed casters (micropatches and microrects; a microquad spans four texels)."""
        return bool(o["bp_solid_columns"]) and o["bp_primitive"] != "MICROQUAD"

    @staticmethod
    def _coverage(o) -> bool:
        """Coarse micropatches read the coverage pyramid, microrects their member statistics (microquads
        neither)."""
        return bool(o["bp_coverage"]) and o["bp_primitive"] != "MICROQUAD"

    def visibility(self, frame, lc, out):
        s, light, view = frame.settings, lc.light, lc.view
        o = self.settings_of(s)
        accumulation, refine = o["bp_accumulation"], REFINE[o["bp_refinement"]]
        bits, primitive = BITS[accumulation], PRIMITIVE[o["bp_primitive"]]
        filter_passes = int(o["bp_filter_passes"]) if bits else 0
        round_ = is_round(light)
        texture = light_texture(light) if bits else None
        depth = lc.structures[DEPTH_MAP]
        maps = lc.structures[PEELED_LAYERS].maps
        w, h = view.width, view.height
        size = (frame.width, frame.height)
        samplers = {"g_irradiance": lc.irradiance, "u_depth": depth}
        levels = level_count(w, h)
        for i, pyramid in enumerate(lc.structures[HSM].pyramids):
            if pyramid is not None:     # None: layer 0 reads the MSSM
                samplers[f"u_hsm{i}"] = pyramid
        n_mssm = 0
        if refine == REFINE_MSSM:
            mssm = lc.structures[MSSM]
            samplers["u_mssm"], n_mssm = mssm.texture, mssm.levels
        ysm_uniforms = {}
        if refine == REFINE_YSM:
            ysm = lc.structures[YSM]
            samplers["u_hsm0"] = ysm.pyramid
            if ysm.texture is not None:
                samplers["u_ysm"] = ysm.texture
            ysm_uniforms = {"u_ysm_base": ysm.base, "u_ysm_levels": ysm.levels, "u_ysm_size": ysm.size}
        if primitive == PRIMITIVE_MICRORECT:
            rects = lc.structures[MICRORECTS]
            for i, (d, e) in enumerate(zip(rects.depth, rects.extent)):
                samplers[f"u_mr_depth{i}"], samplers[f"u_mr_extent{i}"] = d, e
        if self._coverage(o):
            chains = (lc.structures[MICRORECTS].stats if primitive == PRIMITIVE_MICRORECT
                      else lc.structures[COVERAGE].pyramids)
            for i, chain in enumerate(chains):
                samplers[f"u_cov{i}"] = chain
        budget_mode = BUDGET_MODE[o["bp_budget_map"]]
        if budget_mode == BUDGET_IMPORTANCE:
            samplers.update(self._importance_maps(frame, o["bp_budget_image"]))
        force = int(o["bp_force_level"])
        # Blending (2008 §4.2) needs a level that varies: not for an unbounded budget, a forced level or a
        # light without extent (a plain hard test).
        blend = bool(o["bp_blend"]) and budget_mode != BUDGET_UNBOUNDED and force < 0 and not light.is_delta

        shape = light_shape_uniforms(light, view)
        weighted = bits > 0 and o["bp_weighting"] == "IRRADIANCE" and not light.is_delta
        if weighted:
            shape["u_light_half"] = weighted_sun_half(light, shape["u_light_half"])
        n, jx, jy = sample_pattern(accumulation) if bits else (0, (0.5, 0.5), (0.5, 0.5))
        valid = valid_mask(accumulation, round_) if bits else np.zeros((0, 0), bool)
        uniforms = {**lc.uniforms, **shape, "u_round": int(round_),
                    "u_delta": int(light.is_delta), "u_budget": float(o["bp_budget"]), "u_levels": int(levels),
                    "u_budget_border": float(o["bp_budget_border"]), "u_budget_mode": int(budget_mode),
                    "u_budget_low": float(o["bp_budget_low"]),
                    "u_force_level": force, **ysm_uniforms,
                    "u_mssm_levels": int(n_mssm),
                    "u_jitter_x": jx, "u_jitter_y": jy, **({"u_valid": _mask_rows(valid)} if bits else {})}
        info = frame.texture(size, 4)
        images = {0: out, 1: info}
        rgb_tex = None
        if texture is not None:
            colors = sample_colors(texture, accumulation).astype(np.float32)
            lum = luminance(colors).astype(np.float32)
            table = np.concatenate([colors, lum[..., None]], axis=-1) * valid[..., None]
            color_tex = frame.texture((n, n), 4)
            color_tex.write(np.ascontiguousarray(table, np.float32).tobytes())
            samplers["u_sample_color"] = color_tex
            rgb_tex = frame.texture(size, 4)
            images[2] = rgb_tex
            lc.visibility_rgb = rgb_tex         # Combined shades each channel with its own visibility
        defines = {"BITS": bits, "MULTI_JITTER": int(accumulation in MULTI_JITTERED), "PRIMITIVE": primitive,
                   "GAP_FILL": int(bool(o["bp_gap_fill"])),
                   "REFINE": refine, "LAYERS": len(maps), "TEXTURED": int(texture is not None),
                   "WEIGHTED": int(weighted),
                   "NEED_AREA": int(bits == 0 or filter_passes > 0 or frame.settings.debug_passes),
                   "GROW": int(bool(o["bp_query_growth"])), "LOQ": LOQ_INTEGER,
                   "REFIT": REFIT_NONE if primitive == PRIMITIVE_MICROQUAD else REFIT[o["bp_coarse_fit"]],
                   "COVERAGE": int(self._coverage(o)),
                   "SPLIT": int(self._split(o) > 0.0)}
        if defines["MULTI_JITTER"]:
            defines.update(multi_jitter_defines(bits))
        exits = lc.structures.get(SOLID_EXITS)
        if exits is not None and exits.pyramid is not None:      # None: the view holds no closed caster
            defines["COLUMNS"] = 1
            samplers["u_exits"] = exits.pyramid
        defines["REFIT_ITERATIONS"] = refit_iterations(defines)
        if defines["SPLIT"]:
            uniforms["u_split"], uniforms["u_split_extra"] = self._split(o), SPLIT_EXTRA
        frame.progress.check()
        if blend:
            with frame.timings.stage("bp_loq"):
                samplers["u_loq"] = self._loq_map(frame, uniforms, samplers, images, defines, size)
            defines["LOQ"] = LOQ_BLEND
            if s.collect_stats:         # the smoothed level against the pixel's own (the guard, §4.2)
                loq = frame.read(samplers["u_loq"])
                bp = loq[..., 2] >= 0.0
                drop = (loq[..., 2] - loq[..., 0])[bp]
                lc.stats.update({"level_drop_max": float(drop.max()) if bp.any() else 0.0,
                                 "level_change_max": float(np.abs(drop).max()) if bp.any() else 0.0})
        with frame.timings.stage("bp_gather"):
            worst = gather_cells_bound((w, h), len(maps), int(primitive == PRIMITIVE_MICROQUAD), budget_mode,
                                       force, budget_max_of(o), blend, levels)
            chunk_cells = CHUNK_CELLS // cell_iterations(defines, coarse=force != 0 and not (
                force < 0 and budget_mode == BUDGET_UNBOUNDED))
            chunks = 1 if light.is_delta else loops.chunk_count(worst, chunk_cells)
            if chunks == 1:
                frame.dispatch("backprojection/visibility.comp", uniforms, samplers=samplers, images=images,
                               defines=defines)
            else:
                slots = 2 if blend else 1
                state = frame.reserved_buffer(size[0] * size[1] * slots * (bits + 1) * 4)
                for k in range(chunks):
                    frame.progress.check()
                    frame.dispatch("backprojection/visibility.comp",
                                   {**uniforms, **loops.chunk_uniforms(k, chunks, chunk_cells)},
                                   samplers=samplers, images=images, defines={**defines, "CHUNKED": 1},
                                   buffers={4: state})
            lc.stats["gather_dispatches"] = chunks
            lc.stats["depth_layers"] = len(maps)        # after peeling: fewer than bp_layers where one was empty
        if filter_passes:
            with frame.timings.stage("bp_filter"):
                tmp = frame.texture(size, 1)
                src, dst = out, tmp
                for _ in range(filter_passes):
                    frame.dispatch("backprojection/filter.comp", samplers={"u_b": src, "u_info": info},
                                   images={0: dst})
                    src, dst = dst, src
                if src is not out:      # odd number of passes: the result is in tmp; copied on the GPU
                    frame.dispatch("common/copy_r.comp", samplers={"u_src": src}, images={0: out})
        # Share of backprojecting pixels and micro-occluders per such pixel (costs a readback).
        if s.collect_stats or s.debug_passes:
            self._gather_debug(frame, lc, info, rgb_tex, out)

    @staticmethod
    def _importance_maps(frame, image_name: str) -> dict:
        """The importance sources of the budget map (2008 §4.2), per pixel: the budget image's grey value
        stretched over the frame, and the Shadow Importance of the object the camera sees (the receivers drawn
        from the camera with their objects' values, nearest wins). Zero where a source is absent."""
        size = (frame.width, frame.height)
        image = frame.texture(size, 1)
        if image_name:
            grey = frame.snap.images.get(image_name)
            if grey is None:            # not read by the extraction: a file path (CLI, scripts)
                grey = importance.load_grey(image_name, "bp_budget_image")
            image.write(np.ascontiguousarray(importance.resample(grey, size)).tobytes())
        groups: dict[float, set] = {}
        for i, ob in enumerate(frame.snap.objects):
            groups.setdefault(float(ob.importance), set()).add(i)
        if set(groups) <= {0.0}:
            objects = frame.texture(size, 1)
        else:
            from ..gpu.programs import program
            cam = frame.snap.camera
            prog = program(frame.worker, "common/depth.vert", "backprojection/importance.frag")
            objects = frame.rasterise(frame.target(size, 1), prog, cam.view, cam.projection @ cam.view,
                                      role="receiver", clear=(0.0, 0.0, 0.0, 0.0),
                                      draws=[(frozenset(ids), {"u_value": value}) for value, ids in groups.items()])
        return {"u_importance_image": image, "u_importance_objects": objects}

    @staticmethod
    def _loq_map(frame, uniforms, samplers, images, defines, size):
        """Passes 1 and 2 of 2008 §4.2: classify and write each pixel's fractional level ℓ (visibility.comp with
        LOQ_WRITE), then smooth it with the separable bilateral filter (loq.comp), the guard in the last pass."""
        loq, tmp = frame.texture(size, 4), frame.texture(size, 4)
        frame.dispatch("backprojection/visibility.comp", uniforms, samplers=samplers,
                       images={**images, 3: loq}, defines={**defines, "LOQ": LOQ_WRITE})
        for src, dst, direction, guard in ((loq, tmp, (1, 0), 0), (tmp, loq, (0, 1), 1)):
            frame.dispatch("backprojection/loq.comp", {"u_dir": direction, "u_guard": guard,
                                                       "u_depth_jump": LOQ_DEPTH_JUMP},
                           samplers={"u_src": src}, images={0: dst})
        return loq

    def _gather_debug(self, frame, lc, info, rgb_tex, out):
        a = frame.read(info)
        cls, level, count = a[..., 0], a[..., 1], a[..., 2]
        lit_px = cls >= CLASS_LIT
        bp = cls == CLASS_BACKPROJECTED
        lc.stats.update({"pixels": int(lit_px.sum()), "backprojected": int(bp.sum()),
                 "share_backprojected": float(bp.sum() / max(lit_px.sum(), 1)),
                 "share_lit": float((cls == CLASS_LIT).sum() / max(lit_px.sum(), 1)),
                 "share_umbra": float((cls == CLASS_UMBRA).sum() / max(lit_px.sum(), 1)),
                 "mean_count": float(count[bp].mean()) if bp.any() else 0.0,
                 "std_count": float(count[bp].std()) if bp.any() else 0.0,
                 "mean_level": float(level[bp].mean()) if bp.any() else 0.0})
        if frame.settings.debug_passes:
            colour = np.zeros(cls.shape + (3,), np.float32)
            colour[cls == CLASS_LIT] = (0.0, 1.0, 0.0)
            colour[cls == CLASS_UMBRA] = (1.0, 0.0, 0.0)
            colour[bp] = (0.0, 0.0, 1.0)
            lc.debug["BP Class"] = colour
            lc.debug["BP Level"] = level[..., None].astype(np.float32)
            lc.debug["BP Count"] = count[..., None].astype(np.float32)
            if rgb_tex is not None:
                lc.debug["BP Color Visibility"] = frame.read(rgb_tex, 3).copy()
            else:                       # white light: every channel sees the scalar visibility
                lc.debug["BP Color Visibility"] = np.repeat(frame.read(out, 1), 3, axis=-1)
