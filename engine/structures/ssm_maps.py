"""Soft Shadow Maps' per-light maps (Atty et al. 2006, §3.1–3.3, §3.5): occluder maps of the casters (front-most;
farthest back faces for the two-pass method) from the light centre, aligned with the light (square texels, or
of the light's aspect ratio: ssm_view), each texel tagged with its object index; receiver maps (nearest;
farthest receiver, with its normal) made from the receiver pixels the camera sees (glsl/ssm/receivers.comp,
see techniques/ssm.py); and the micro-patch list with each patch's penumbra extent (§3.3). The paper builds
the list on the CPU; here glsl/ssm/patches.comp builds it on the GPU, row for row what `patch_list` (the numpy
reference) gives, and only the patch count and the work estimate come back. The occluder-map resolution is
lowered until the scatter's estimated work fits the budget, so maps and patch list are one structure.

Also here: the object-role split (Object → Penumbra → Shadow Role) and the camera-view receiver mask that
SSM's projection reads (`receiver_mask`, its own structure)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core import lightview
from ..core.light_shape import light_half_extent, penumbra_spread
from ..core.lightview import LightView
from ..core.shader_constants import EMPTY_DEPTH, NO_OCCLUDER
from ..gpu.frame import resource_bytes
from ..gpu.programs import program
from . import structure

SSM_MAPS = "ssm_maps"
RECEIVER_MASK = "ssm_receiver_mask"
CASTER_ROLES = ("CASTER", "BOTH")
RECEIVER_ROLES = ("RECEIVER", "BOTH")
# Relative depth separation (fraction of the receiver's linear depth) a micro-patch needs to occlude a
# receiver, zo < zr·(1 − ε): float32 rounding only (the receiver's tangent plane keeps its own surface out).
DEPTH_EPSILON = 1e-5


def split_roles(snap) -> tuple[list[int], list[int]]:
    """Object indices whose micro-patches occlude (CASTER/BOTH and casting shadows) and whose surfaces
    receive (RECEIVER/BOTH and seen by the camera)."""
    casters = [i for i, o in enumerate(snap.objects) if o.caster and getattr(o, "role", "BOTH") in CASTER_ROLES]
    receivers = [i for i, o in enumerate(snap.objects)
                 if o.receiver and getattr(o, "role", "BOTH") in RECEIVER_ROLES]
    return casters, receivers


def role_warnings(snap) -> list[str]:
    casters, receivers = split_roles(snap)
    out = []
    if not casters:
        out.append(f"SSM: scene '{snap.name}' has no object with Shadow Role Caster or Both: no shadows.")
    if not receivers:
        out.append(f"SSM: scene '{snap.name}' has no object with Shadow Role Receiver or Both: no shadows.")
    return out


def ssm_view(view: LightView, half, size: int, light_aspect: bool = False) -> LightView:
    """The pipeline's light view, aligned with the light, with square texels, or with `light_aspect` texels
    of the light's aspect ratio (§3.2: micro-patches axis-aligned with the light and of its aspect ratio);
    the longer side in texels gets `size`. The window grows symmetrically on the short side to a whole
    number of texels. A sun's eye moves back along its axis so that every depth in the view is positive.

    Square texels by default (deviation): the paper gives texels the light's aspect so that a patch's
    penumbra extent is a pyramid (§3.3); patch_list computes the extent per axis, which needs no such
    shape. Texels of a sliver light's aspect are that many times longer than square ones on one side
    (fuzz 9001: a 0.30 × 0.035 m light over a view 80° wide, texels 0.29 × 0.034 tan, 41 × 256 of them),
    and shadow edges, the receivers' slope-scaled bias and their normal offset (common/light_view.glsl,
    from the texel's longer side) all grow with that side: the bias kept an occluder 1.6 m above the floor
    from shadowing it."""
    x0, x1, y0, y1 = view.window
    # 1e-30 window units: a degenerate (zero-width) window still divides; 1e-9 texels: a window that is a
    # whole number of texels up to rounding does not get one more.
    w, h = max(x1 - x0, 1e-30), max(y1 - y0, 1e-30)
    aspect = 1.0                                                     # texel width / height
    if light_aspect and half[0] > 0 and half[1] > 0:
        aspect = float(half[0]) / float(half[1])
    if w >= h * aspect:
        width = size
        tw = w / width
        th = tw / aspect
        height = int(min(max(math.ceil(h / th - 1e-9), 1), size))
        grow = (height * th - h) / 2.0
        window = (x0, x1, y0 - grow, y1 + grow)
    else:
        height = size
        th = h / height
        tw = th * aspect
        width = int(min(max(math.ceil(w / tw - 1e-9), 1), size))
        grow = (width * tw - w) / 2.0
        window = (x0 - grow, x1 + grow, y0, y1)
    world_to_local, near, far = view.view, view.near, view.far
    if view.is_ortho:
        # A sun's frame sits at the sun object, so casters behind it have depth ≤ 0, which SSM's maps read as
        # empty (depth 0 is the far maps' "no receiver", and the spread and the depth gap are measured from
        # the eye): move the eye back along the light's axis until the nearest depth is 1 % of the range. A
        # sun's spread depends on depth differences only, so nothing else changes.
        lead = 0.01 * max(far - near, 1e-9)
        if near < lead:
            shift = np.eye(4)
            shift[2, 3] = near - lead           # local z' = z + near − lead: depth' = depth − near + lead
            world_to_local = shift @ np.asarray(world_to_local, float)
            near, far = lead, far - near + lead
    proj = (lightview.ortho if view.is_ortho else lightview.frustum)(window, near, far)
    return LightView(world_to_local, proj, width, height, near, far, view.is_ortho,
                     tuple(float(v) for v in window), view.clamped)


# Sloped facets (glsl/ssm/patch.glsl edge_depth): two neighbouring texels of one object are one surface while
# their depths differ by at most this many texel widths (at 128², 8 → 16: tilted 0.0079 → 0.0070, suzanne
# 0.0182 → 0.0190; 4: 0.0153, 0.0233). An edge then lies halfway between their depths, so no nearer than
# FACET_SLOPE / 2 texel widths in front of its patch: the extents below reach that far.
FACET_SLOPE = 8.0

OCCLUDER_MAPS = ("front", "back")       # SsmMaps.maps keys of the occluder maps (back: two passes, §3.5)


def facet_reach(view: LightView, facets: bool) -> float:
    """How far in front of its patch a sloped facet's edge may lie: in metres for a sun's view, as a share of
    the patch's depth for a perspective one (0 for the paper's flat micro-patches)."""
    return 0.5 * FACET_SLOPE * max(view.texel_size()) if facets else 0.0


def patch_list(depth_id: np.ndarray, view: LightView, half, zr_max: float, bias_texels: float,
               facets: bool = False):
    """Micro-patches of an occluder map and their penumbra extents (§3.3): the reference that
    glsl/ssm/patches.comp reproduces on the GPU (the renderer uses that one; tests compare the two).

    The extent of a patch [lo, hi] at depth zo on the plane of a receiver at depth zr is
    [lo − h·s, hi + h·s] with s = penumbra_spread(zo, zr) — the section of the patch's penumbra pyramid,
    whose apex is C_L + r/(1+r)·(C_P − C_L) with r = LL'/PP' (§3.3; at zr the paper's RR' = LL'(zr − z_apex)/z_apex
    equals the patch's projection zr/zo·PP' plus LL'(zr − zo)/zo, the same rectangle). It grows with zr, so
    the farthest receiver depth bounds it; with sloped `facets` it is taken at the facet's nearest possible
    edge (facet_reach). Returns (float32 (M, 8) rows: x0, y0, x1, y1 in texels, i, j,
    zo, object; estimated SSM texel updates). `depth_id`: (H, W, 2) depth and object index per texel."""
    depth, ids = depth_id[..., 0], depth_id[..., 1]
    valid = (depth > 0.0) & (depth < EMPTY_DEPTH)
    j, i = np.nonzero(valid)
    if i.size == 0 or not np.isfinite(zr_max):
        return np.zeros((0, 8), np.float32), 0.0
    zo = depth[j, i].astype(np.float64)
    tw, th = view.texel_size()
    keep = zo < zr_max * (1.0 - bias_texels)
    zo, i, j = zo[keep], i[keep], j[keep]
    obj = ids[j, i]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        # 1e-30 m: a patch on the light plane (zo = 0) gets a huge, finite spread instead of a division by 0.
        reach = facet_reach(view, facets)
        near = zo - reach if view.is_ortho else zo * (1.0 - reach)      # patches.comp's arithmetic, in order
        s = np.maximum(penumbra_spread(np.maximum(near, 1e-30), zr_max, view.is_ortho), 0.0)
        gx = np.minimum(half[0] * s / tw, 4.0 * view.width)     # clamp: an occluder at the light plane
        gy = np.minimum(half[1] * s / th, 4.0 * view.height)    # covers the map, never infinity
    rect = np.stack([np.clip(i - gx, 0, view.width), np.clip(j - gy, 0, view.height),
                     np.clip(i + 1 + gx, 0, view.width), np.clip(j + 1 + gy, 0, view.height)], axis=1)
    area = np.clip(rect[:, 2] - rect[:, 0], 0, None) * np.clip(rect[:, 3] - rect[:, 1], 0, None)
    keep = area > 0.0
    rows = np.zeros((int(keep.sum()), 8), np.float32)
    rows[:, 0:4] = rect[keep]
    rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7] = i[keep], j[keep], zo[keep], obj[keep]
    return rows, float(area[keep].sum())


PATCH_ROW_BYTES = 32        # one row of patch_list: 8 float32 (glsl/ssm/patches.comp's Patch)
_PATCH_RUN = 32             # texels per invocation of patches.comp (its RUN)
_PATCH_THREADS = 64         # its work group size (THREADS) outside PASS 2
_RUN_BYTES = 16             # patches.comp's Run: count, offset, work (double)
_HEADER_BYTES = 16          # patches.comp's Scratch header: count, pad, work (double)


def _quantised(nbytes: int) -> int:
    """nbytes rounded up to a multiple of 1/8 of its power of two (and of 256 bytes): pooled buffers, keyed
    by their exact size, are reused while the patch count varies a little, for at most 1/8 more memory
    above 4 KiB."""
    step = 1 << max(8, (int(nbytes) - 1).bit_length() - 4)
    return -(-int(nbytes) // step) * step


@dataclass
class PatchList:
    """One occluder map's micro-patches on the GPU: the first `count` rows of `buffer` (None when there are
    none), in patch_list's layout and order; `work`: the estimated scatter texel updates."""
    buffer: object | None
    count: int
    work: float

    @property
    def nbytes(self) -> int:
        return resource_bytes(self.buffer)

    def read(self) -> np.ndarray:
        """The rows as patch_list returns them, (count, 8) float32 (tests compare the two)."""
        if not self.count:
            return np.zeros((0, 8), np.float32)
        return np.frombuffer(self.buffer.read(self.count * PATCH_ROW_BYTES), np.float32).reshape(-1, 8).copy()


@dataclass
class _PatchCounts:
    """patches.comp's passes 0–2 for the occluder maps of one light view, before the rows are written."""
    view: LightView
    uniforms: dict
    occluders: list             # occluder-map textures
    far: object                 # buffer: zr_max (float bits)
    scratch: list               # per occluder map: header and run counts/offsets/work
    counts: list
    works: list

    def give_back(self, frame) -> None:
        for buf in (self.far, *self.scratch):
            frame.give_back(buf)


def _count_patches(frame, view: LightView, half, occluders: list, far_map, bias: float,
                   reach: float = 0.0) -> _PatchCounts:
    """Patch count and work of each occluder map, computed on the GPU; 16 bytes per map come back."""
    size = (view.width, view.height)
    runs = -(-view.width * view.height // _PATCH_RUN)
    grid = (-(-runs // _PATCH_THREADS), 1, 1)
    far = frame.reserved_buffer(_quantised(4))
    far.write(np.zeros(1, np.uint32).tobytes())           # atomicMax from 0: no receiver yet
    uniforms = {"u_runs": runs, "u_half": tuple(half), "u_texel": view.texel_size(), "u_bias": float(bias),
                "u_ortho": int(view.is_ortho), "u_facet_reach": float(reach)}
    frame.dispatch("ssm/patches.comp", uniforms, samplers={"u_map": far_map}, buffers={1: far},
                   defines={"PASS": 0}, size=size, groups=grid)
    scratch = []
    for occ in occluders:
        buf = frame.reserved_buffer(_quantised(_HEADER_BYTES + _RUN_BYTES * runs))
        for pass_, groups in ((1, grid), (2, (1, 1, 1))):
            frame.dispatch("ssm/patches.comp", uniforms, samplers={"u_map": occ}, buffers={0: buf, 1: far},
                           defines={"PASS": pass_}, size=size, groups=groups)
        scratch.append(buf)
    counts, works = [], []
    for buf in scratch:
        raw = buf.read(_HEADER_BYTES)
        counts.append(int(np.frombuffer(raw, np.uint32, 1)[0]))
        works.append(float(np.frombuffer(raw, np.float64, 1, 8)[0]))
    return _PatchCounts(view, uniforms, list(occluders), far, scratch, counts, works)


def _write_patches(frame, counted: _PatchCounts) -> list[PatchList]:
    """patches.comp's pass 3: the rows of every occluder map into a buffer of the frame's pool."""
    view = counted.view
    grid = (-(-counted.uniforms["u_runs"] // _PATCH_THREADS), 1, 1)
    out = []
    for occ, buf, count, work in zip(counted.occluders, counted.scratch, counted.counts, counted.works):
        if not count:
            out.append(PatchList(None, 0, work))
            continue
        rows = frame.reserved_buffer(_quantised(count * PATCH_ROW_BYTES))
        frame.dispatch("ssm/patches.comp", counted.uniforms, samplers={"u_map": occ},
                       buffers={0: buf, 1: counted.far, 2: rows}, defines={"PASS": 3},
                       size=(view.width, view.height), groups=grid)
        out.append(PatchList(rows, count, work))
    counted.give_back(frame)        # GL keeps command order: pass 3 still reads them
    return out


def reference_patches(frame, maps: "SsmMaps") -> list:
    """patch_list's (rows, work) for each occluder map of `maps`, computed on the CPU from the maps read
    back: what `maps.patches` must equal (tests). zr_max is the farthest valid receiver depth."""
    far = frame.read(maps.maps["far"])[..., 0]
    valid = (far > 0.0) & (far < EMPTY_DEPTH)
    zr_max = float(far[valid].max()) if valid.any() else math.inf
    return [patch_list(frame.read(occ), maps.view, maps.half, zr_max, maps.bias, maps.facets)
            for occ in maps.occluder_maps()]


def casters_reach_receivers(light, world_to_local, half, is_ortho: bool, casters, receivers) -> bool:
    """False when the casters' penumbrae cannot reach the visible receivers: all casters behind the
    receivers, or their windows (widened by the largest penumbra) disjoint. Conservative: True when a box
    reaches the light plane."""
    def corners(box):
        lo, hi = (np.asarray(v, float) for v in box)
        return lightview.to_local(world_to_local, lightview.box_corners(lo, hi))
    c, r = corners(casters), corners(receivers)
    cd, rd = -c[:, 2], -r[:, 2]
    if cd.min() >= rd.max():
        return False
    if is_ortho:
        cw, rw = c[:, :2], r[:, :2]
    else:
        if cd.min() <= 1e-9 or rd.min() <= 1e-9:    # metres: a box touching the light plane reaches all
            return True
        cw, rw = c[:, :2] / cd[:, None], r[:, :2] / rd[:, None]
    grow = np.asarray(half) * penumbra_spread(cd.min(), rd.max(), is_ortho)
    lo_c, hi_c = cw.min(axis=0) - grow, cw.max(axis=0) + grow
    lo_r, hi_r = rw.min(axis=0), rw.max(axis=0)
    return bool(np.all(lo_c < hi_r) and np.all(lo_r < hi_c))


@dataclass
class SsmMaps:
    """Maps of one light view, or `skipped` when no caster can shadow a visible receiver (then only the
    role lists are set)."""
    casters: list
    receivers: list
    half: tuple = (0.0, 0.0)                 # light half extent (metres, or tan for a sun)
    view: LightView | None = None            # the aspect-corrected view the maps were drawn with
    maps: dict = field(default_factory=dict)  # front, back (two-pass), near, far, receivers (packed)
    patches: list = field(default_factory=list)     # per occluder map: its PatchList
    bias: float = DEPTH_EPSILON
    skipped: bool = False
    facets: bool = False                     # sloped facets: the extents reach their edges (facet_reach)
    horizon_cut: bool = False                # some receiver's horizon cuts the light (glsl/ssm/receivers.comp)

    @property
    def nbytes(self) -> int:
        return resource_bytes(self.maps) + sum(p.nbytes for p in self.patches)

    def occluder_maps(self) -> list:
        """The occluder-map textures, in the order of `patches` (front; back with two passes)."""
        return [self.maps[name] for name in OCCLUDER_MAPS[:len(self.patches)]]


def _draw_maps(frame, lc, view, half, casters, two_pass, mask) -> tuple[dict, object]:
    """Occluder maps (front-most casters; farthest back faces, §3.5), linear depth from the light centre and
    object index (empty: NO_OCCLUDER or 0, index −1), and the receiver maps of the camera's receiver pixels
    (glsl/ssm/receivers.comp): near/far (depth, receiver point; 0: none), near_n/far_n (normal, bias) and
    near_c/far_c (the receiver's own plane); and a 1×1 flag, non-zero where some receiver's horizon cuts the
    light (`half`: its half extent), which compiles the scatter's clipped weights in (read with the patch
    counts, `_horizon_cut`: one wait for the GPU instead of two)."""
    prog = program(frame.worker, "common/depth.vert", "ssm/depth.frag")
    jobs = [("front", casters, False, False)]
    if two_pass:
        jobs.append(("back", casters, True, True))
    size = (view.width, view.height)
    out = {}
    for name, objects, farthest, back_only in jobs:
        draws = [(frozenset((int(index),)), {"u_object": float(index)}) for index in objects]  # tagged draws
        out[name] = frame.rasterise(frame.target(size, 2), prog, view.view, view.view_proj, role="caster",
                                    draws=draws, farthest=farthest, uniforms={"u_back_only": int(back_only)},
                                    clear=(0.0 if farthest else NO_OCCLUDER, -1.0, 0.0, 0.0))
    bits = {0: frame.texture(size, 1, dtype="u4"), 1: frame.texture(size, 1, dtype="u4")}    # zero-filled
    for name in ("near", "near_n", "far", "far_n"):
        out[name] = frame.texture(size, 4)
    for name in ("near_c", "far_c"):
        out[name] = frame.texture(size, 1)
    uniforms = {**view.uniforms(), **frame.bias_uniforms, "u_has_mask": int(mask is not None)}
    samplers = {"g_irradiance": lc.irradiance, "u_receiver_mask": mask if mask is not None else bits[0]}
    cut = frame.texture((1, 1), 1, dtype="u4")       # zero-filled
    frame.dispatch("ssm/receivers.comp", {**uniforms, "u_half": half}, samplers=samplers,
                   images={**bits, 2: cut}, defines={"PASS": 0})
    frame.dispatch("ssm/receivers.comp", uniforms, samplers=samplers, defines={"PASS": 1},
                   images={**bits, 2: out["near"], 3: out["near_n"], 4: out["far"], 5: out["far_n"],
                           6: out["near_c"], 7: out["far_c"]})
    for t in bits.values():
        frame.give_back(t)
    return out, cut


def _horizon_cut(frame, cut) -> bool:
    """_draw_maps' flag, read once the patch counts have been (the GPU is done with it by then)."""
    flag = bool(np.frombuffer(cut.read(), np.uint32)[0])
    frame.give_back(cut)
    return flag


# A penumbra this many texels wide is drawn by the map's patches, not by its texel steps (refined_size).
PENUMBRA_TEXELS = 4.0


def refined_size(size: int, fine_size: int, work: float, patches: int) -> int:
    """The occluder-map size at which the light's mean penumbra spans PENUMBRA_TEXELS texels, at most
    `fine_size` and never below `size`. `work / patches` is the mean number of texels a patch updates, the
    square of its penumbra's width in texels, which grows in step with the map's size. A light whose patches
    update about one texel each (a point-like light) casts hard shadows, and a map of a few hundred texels
    draws their edges in steps that a hard shadow map of `fine_size` does not have: a sheet cutting through a
    ball under a 2 mm light (fuzz 28164) left a band of the ball lit along the cut, mae_shadow 0.42 at 256
    texels, 0.13 at 1024 (HARD 0.12)."""
    if patches <= 0 or fine_size <= size:
        return size
    width = math.sqrt(max(work, 0.0) / patches)
    if width >= PENUMBRA_TEXELS:
        return size
    return int(min(fine_size, size * PENUMBRA_TEXELS / max(width, 1e-9)))


@structure(SSM_MAPS, requires=(RECEIVER_MASK,))
def build(frame, lc, size: int, budget: float, two_pass: bool, light_aspect: bool = False, facets: bool = False,
          fine_size: int = 0):
    """`size`: texels along the longer side; `budget`: SSM texel updates allowed before the maps are made
    coarser (§5.1); `two_pass`: also the back-face occluder map (§3.5); `light_aspect`: texels of the light's
    aspect ratio (§3.2) instead of square ones (ssm_view); `facets`: the patches' extents sized for sloped
    facets (glsl/ssm/patch.glsl); `fine_size` (0: off): a light whose penumbrae span under PENUMBRA_TEXELS
    texels gets finer maps, up to this size (refined_size)."""
    light = lc.light
    for text in role_warnings(frame.snap):
        frame.warn(text)
    casters, receivers = split_roles(frame.snap)
    bounds = frame.geometry.object_bounds()
    # A flat caster every receiver lies on the light side of shadows nothing (a BOTH floor, at any tilt).
    flags = np.zeros(len(frame.snap.objects), bool)
    kept = []
    for index in casters:
        flags[:] = False
        flags[index] = True
        if lightview.shadowing_caster_bounds(light, bounds, flags, lc.receivers, lc.receiver_sides) is not None:
            kept.append(index)
    casters = kept
    half = tuple(float(v) for v in light_half_extent(light, lc.view.face))
    if not casters or not receivers:
        frame.count(ssm_lights_skipped=1)
        return SsmMaps(casters, receivers, half, skipped=True)
    caster_box = (bounds[casters, 0].min(axis=0), bounds[casters, 1].max(axis=0))
    if not casters_reach_receivers(light, lc.view.view, half, lc.view.is_ortho, caster_box, lc.receivers):
        frame.count(ssm_lights_skipped=1)   # the casters' penumbrae fall nowhere near a visible receiver
        return SsmMaps(casters, receivers, half, skipped=True)

    bias = DEPTH_EPSILON
    budget *= lc.share          # the light's budget, split over its views by the pixels each holds
    occluder_maps = OCCLUDER_MAPS if two_pass else OCCLUDER_MAPS[:1]
    attempts = 6
    asked = size
    refining = fine_size > size
    for attempt in range(attempts):
        view = ssm_view(lc.view, half, size, light_aspect)
        with frame.timings.stage("ssm_maps"):
            maps, cut = _draw_maps(frame, lc, view, half, casters, two_pass, lc.structures[RECEIVER_MASK])
            counted = _count_patches(frame, view, half, [maps[n] for n in occluder_maps], maps["far"], bias,
                                     facet_reach(view, facets))
            horizon_cut = _horizon_cut(frame, cut)
        work = sum(counted.works)
        # Finer while the penumbrae stay under PENUMBRA_TEXELS (a point light's do at any size); once a step
        # gains under 10 %, or the budget has to make the maps coarser, never again.
        finer = refined_size(size, fine_size, work, sum(counted.counts)) if refining else size
        if finer > size * 1.1 and attempt < attempts - 1:
            counted.give_back(frame)
            size = finer
            continue
        refining = False
        if work <= budget or size <= 32 or attempt == attempts - 1:     # the last attempt's maps are kept
            break
        counted.give_back(frame)
        new = max(32, int(size * (budget / work) ** 0.25 * 0.95))
        if lc.share == 1.0 and new < asked:     # a view of part of the light's pixels is lowered by design
            frame.warn(f"SSM: light '{light.name}': occluder map lowered from {size} to {new} texels to "
                       f"keep the scatter within ssm_budget ({work / 1e6:.0f} M texel updates)")
        size = new
    with frame.timings.stage("ssm_maps"):
        patches = _write_patches(frame, counted)
    frame.count(ssm_patches=sum(counted.counts), ssm_work=int(work), ssm_map_size=size)
    skipped = all(p.count == 0 for p in patches)
    if skipped:
        frame.count(ssm_lights_skipped=1)
    return SsmMaps(casters, receivers, half, view, maps, patches, bias, skipped, facets=facets,
                   horizon_cut=horizon_cut)


@structure(RECEIVER_MASK)
def build_receiver_mask(frame, lc):
    """Camera-resolution mask (g = 1) of the pixels whose nearest surface is a receiver, or None when every
    camera-visible object is one. SSM's receiver maps take only those pixels, and its projection shadows
    only those: depth matching alone cannot tell a CASTER-only surface that lies between two receivers
    (seen from the light centre) from a receiver there."""
    _casters, receivers = split_roles(frame.snap)
    visible = [i for i, o in enumerate(frame.snap.objects) if o.receiver]
    others = [i for i in visible if i not in set(receivers)]
    if not others or not receivers:
        return None
    cam = frame.snap.camera
    prog = program(frame.worker, "common/depth.vert", "ssm/depth.frag")
    draws = [(frozenset(int(i) for i in objects), {"u_object": flag})
             for flag, objects in ((1.0, receivers), (0.0, others))]
    return frame.rasterise(frame.target((frame.width, frame.height), 2), prog, cam.view,
                           cam.projection @ cam.view, role="receiver", draws=draws,
                           clear=(0.0, 0.0, 0.0, 0.0), uniforms={"u_back_only": 0})
