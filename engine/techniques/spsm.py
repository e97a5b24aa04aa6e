"""SPSM: sub-pixel shadow maps (Lecocq, Marvie, Sourimant, Gautron 2014, "Sub-Pixel Shadow Mapping").

Hard shadows from the light's centre, like HARD, but the map keeps the closest triangle of every texel any
caster touches (the `conservative_map` structure: conservative rasterization §3.2, the 128-bit texel §3.3,
the slope quantiser §3.4), so that a receiver can be tested against real geometry at sub-texel precision.

Per pixel (glsl/spsm/visibility.comp):
  1. Eq. 1 + Algorithm 1 against the centre texel's triangle: lit when the receiver lies on it, shadowed
     when it occludes the receiver (§4.1, one look-up);
  2. the same test against the 3×3 neighbourhood: a hit is shadowed (§4.1);
  3. otherwise uncertain: consistent depths (§4.2, Fig. 9) give the 3×3 bitmask of occluders in front; a
     pattern table (`PATTERNS`, below) turns its ring into up to two shadow directions; the boundary
     vertices of the front triangles on that tangent's occluder side (vertices facing the lit side, none
     strictly inside another front triangle), projected on each tangent axis, make the piecewise-linear φ,
     and the receiver is shadowed where d(p) > φ(t(p)) (§4.2, Fig. 10; two tangents combine as below);
  4. antialiasing: uncertain pixels evaluate the same φ at `spsm_aa_samples` positions of their
     footprint in the map (§5).

Departures, measured against Cycles (bench --study spsm, 128² images, mismatched pixels):
  * the receiver's normal offset keeps its depth but not its sideways shift in the map, which at sub-texel
    precision moved outer shadow edges outwards (stress-style test scene at 64²: 103 → 59 mismatched);
  * shadow-terminator pixels (shading normal towards the light, the flat triangle away from it) are
    shadowed by their own mesh geometrically; Cycles lifts their shadow rays off the triangle (its
    terminator geometry offset) and lights most of them. SPSM decides those pixels as HARD does, with the
    hard depth map (a second, cheap need): 28/23/16 → 13/10/11 (HARD: 28/23/16; SPSM shadowing them:
    14/18/23). "As HARD does" means HARD's receiver: the lifted point of common/light_view.glsl
    (pixel_receiver) and its tangent-plane rule, so that a receiver lit only by the rest of a wide light (a
    ball's far half under a 2.5 rad sun) is not shadowed by its own object (tests/test_spsm.py: 6.6 % of the
    pixels Cycles sees lit were dark with the unlifted point and a plain depth test, 0 now). The cost is
    HARD's: where the part of a wide light above such a face is hidden by the object's own neighbourhood,
    SPSM lights the face as HARD does (fuzz 5012, a 0.67 rad sun: 0.231 → 0.285, HARD 0.285, bound 0.258);
    over seeds 5000–5039, 6000–6039 and 7400–7439 at 64² it goes from 10 scenes over the bound to 3. Receivers within 3° of edge-on (city's walls at 89.8°) are decided the same way: there one
    texel spans tens of texel-widths of depth (city 4096²: 78 → 21, HARD 32);
  * a full ring of occluders in front with none over p is the paper's umbra, or a gap in occluders finer
    than a texel (its "shadow fusion", §6.4): the hard map decides it (thin 512²: 1229 → 903, HARD 813).

The pattern set (the paper's Fig. 8 is not in its text; derived here, `pattern_directions`): the 8 ring
texels in order E, NE, N, NW, W, SW, S, SE plus the centre's own bit. A corner texel is 4-connected to its
two edge neighbours, edges only through corners or the centre.
  * Centre not in front: the set ring texels split into 4-connected groups; a corner whose two edge
    neighbours are unset is isolated and dropped (§4.2, Fig. 7c). Each group is an occluder beside the
    centre, its tangent faces the normalised sum of its offsets; the two largest are kept (three or four
    groups, checkerboards, keep two: a limit) and their shadows unite.
  * Centre in front: one blob through the centre (isolated corners dropped). A lopsided blob (|Σ offsets|
    ≥ half its texel count) is an edge facing that sum; a symmetric one (a line through the centre) is a
    thin occluder along the principal axis of its texels, with both normals, whose shadows intersect.
  * A full ring goes to the hard map (above); no usable pattern (only the centre, only isolated corners)
    leaves p lit: no neighbour says an occluder reaches past the stored triangles.
"""
from __future__ import annotations

import numpy as np

from ..structures.conservative_map import CONSERVATIVE_MAP, QUANTISERS
from .base import DEPTH_MAP, Option, Technique

RING = ((1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1))   # E NE N NW W SW S SE
# Pixel classes of the class image (visibility.comp's C_*): how each pixel was decided.
CLASSES = {1: "lit_1", 2: "shadow_1", 3: "shadow_3x3", 4: "recovered", 5: "uncertain"}


def ring_groups(mask: int) -> list[list[int]]:
    """4-connected groups of set ring texels (indices into RING) when the centre is not in front; isolated
    corners dropped."""
    bits = [(mask >> i) & 1 for i in range(8)]
    seen, groups = set(), []
    for start in range(8):
        if not bits[start] or start in seen:
            continue
        group, stack = [], [start]
        seen.add(start)
        while stack:
            i = stack.pop()
            group.append(i)
            # Along the ring every neighbour pair is one edge and one corner: 4-adjacent.
            for j in ((i + 1) % 8, (i - 1) % 8):
                if bits[j] and j not in seen:
                    seen.add(j)
                    stack.append(j)
        if len(group) == 1 and group[0] % 2 == 1:
            continue            # an isolated corner
        groups.append(sorted(group))
    return groups


def _unit(v) -> np.ndarray | None:
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else None


def pattern_directions(mask: int, centre: bool) -> list[np.ndarray]:
    """Up to two unit shadow directions (towards the occluder side of each tangent) for a 3×3 mask: the
    ring bits and whether the centre texel is in front."""
    if not centre:
        # Occluders beside the centre only: one tangent per group, facing it (shadows unite).
        dirs = [_unit(np.sum([RING[i] for i in g], axis=0)) for g in sorted(ring_groups(mask), key=len,
                                                                             reverse=True)]
        return [d for d in dirs if d is not None][:2]
    # The centre is in front: every set edge texel joins it, corners through their edges; a corner alone
    # is isolated. One blob through the centre.
    bits = [(mask >> i) & 1 for i in range(8)]
    kept = [i for i in range(8) if bits[i] and (i % 2 == 0 or bits[(i + 1) % 8] or bits[(i - 1) % 8])]
    if not kept:
        return []
    offsets = np.array([RING[i] for i in kept], np.float64)
    gradient = offsets.sum(axis=0)
    if np.linalg.norm(gradient) >= 0.5 * len(kept):
        return [_unit(gradient)]            # an edge: the blob lies on one side
    # Symmetric about the centre: a thin occluder crossing it along the principal axis of the set texels;
    # it is bounded on both sides, so the two normals' shadows intersect.
    w, v = np.linalg.eigh(offsets.T @ offsets)
    axis = v[:, np.argmax(w)]
    normal = np.array([-axis[1], axis[0]])
    return [normal, -normal]


def pattern_table() -> np.ndarray:
    """(512, 4) float32: the directions of every mask (index: ring bits | centre << 8), (0, 0) where there
    is none."""
    table = np.zeros((512, 4), np.float32)
    for index in range(512):
        for k, d in enumerate(pattern_directions(index & 0xFF, bool(index >> 8))):
            table[index, 2 * k:2 * k + 2] = d
    return table


PATTERNS = pattern_table()


class SubPixelShadowMaps(Technique):
    identifier = "SPSM"
    label = "Sub-pixel shadow map"
    description = ("Hard shadows from the light centre with sub-texel edges: a conservative triangle map, "
                   "3×3 look-ups and silhouette recovery (Lecocq et al. 2014)")
    needs = (CONSERVATIVE_MAP, DEPTH_MAP)    # the hard map decides shadow-terminator pixels, as HARD does
    rim_views = True
    options = (
        Option("spsm_quantiser", "POW5", "Slope Quantiser", "How the texel stores its depth slopes (§3.4)",
               items=(("POW5", "Power 5 (paper)", "Q(d) = 127·(1 + ((2/π)·atan d)^5): fine at grazing angles"),
                      ("POW3", "Power 3", "The same with n = 3"),
                      ("LINEAR", "Linear 8-bit", "8 bits linear in the slope angle (n = 1)"),
                      ("FLOAT", "Float (ablation)", "Unquantised slopes from a second texture: not the "
                                                    "128-bit texel, for comparison only"))),
        Option("spsm_recovery", True, "Silhouette Recovery",
               "Recover the shadow edge of uncertain pixels from the 3×3 neighbourhood (§4.2)"),
        Option("spsm_aa_samples", 8, "Edge Samples",
               "Samples per uncertain pixel along the recovered edge (§5); 1 turns antialiasing off", 1, 32),
    )
    debug_passes = (("SPSM Class", 1, "X", "VALUE"),)   # CLASSES codes
    coarse = {"spsm_aa_samples": 1}                     # the viewport's first frame: no edge samples

    def visibility(self, frame, lc, out):
        s = frame.settings
        cmap = lc.structures[CONSERVATIVE_MAP]
        size = (frame.width, frame.height)
        classes = frame.texture(size, 1)
        patterns = frame.texture((512, 1), 4)
        patterns.write(PATTERNS.tobytes())
        samplers = {"g_irradiance": lc.irradiance, "u_texels": cmap.texels, "u_slope_table": cmap.slope_table,
                    "u_patterns": patterns, "u_depth_map": lc.structures[DEPTH_MAP]}
        defines = {}
        if cmap.slopes is not None:
            samplers["u_slopes"] = cmap.slopes
            defines["SPSM_FLOAT_SLOPES"] = 1
        uniforms = {**lc.uniforms, **cmap.uniforms(), "u_recovery": int(bool(s.option("spsm_recovery"))),
                    "u_aa_samples": int(s.option("spsm_aa_samples"))}
        frame.dispatch("spsm/visibility.comp", uniforms, samplers=samplers, images={0: out, 1: classes},
                       defines=defines)
        if s.collect_stats or s.debug_passes:
            cls = frame.read(classes)[..., 0]
            decided = max(int((cls > 0).sum()), 1)
            lc.stats.update({"pixels": decided,
                             **{f"share_{name}": float((cls == code).sum() / decided)
                                for code, name in CLASSES.items()}})
            if s.debug_passes:
                lc.debug["SPSM Class"] = cls[..., None].copy()


