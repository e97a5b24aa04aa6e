"""Averaged shadow maps (user-facing identifier REFERENCE): the average of N hard shadow maps rendered from
stratified points of the light — the "1024 shadow maps" ground truth the soft-shadow-map papers compare
against (e.g. Atty et al. §4.1). Penumbra's own ground truth is Cycles (engine/measure/reference.py).

Sample points: an R2 low-discrepancy set over the square, mapped to the disk by Shirley & Chiu's concentric
map for round lights. Sphere lights are sampled over their great disk facing the receivers (the view's XY
plane) where the view is narrow, else over the ball whose projection along any direction is that disk
(_fills_ball; a true sphere over its ball unless the disk is within a percent of it); a true sphere's
receivers outside it over its ball without the casters inside it, those inside it over its surface; suns
uniformly over their cone of directions, each weighted by the receiver's cosine. Each map's view keeps the
light's axes and is refitted from the sample point, its texel grid shifted by a sub-texel amount of its own
(grid_shift). A spot whose cone lets each receiver see only part of its disk gets its samples where some
receiver's footprint lies (cone_region), as many as keep the setting's count in each footprint
(cone_sample_count).
"""
from __future__ import annotations

import numpy as np

from ..core import lightview
from ..core.light_shape import light_half_extent, spot_cone_tans
from ..core.shading import spot_uniforms
from ..core.shader_constants import (SIDE_ALL, SIDE_BEYOND_DISK, SIDE_INSIDE, SIDE_OUTSIDE, WEIGHT_AREA, WEIGHT_NONE,
                                     WEIGHT_SPHERE, WEIGHT_SUN)
from ..core.snapshot import AREA, DISK, ELLIPSE, POINT, SPOT, SUN, Light
from ..gpu.frame import MAX_DEPTH_LAYERS
from ..structures import need
from ..structures.lit_umbra import LIT_UMBRA
from .base import MAP_SIZE_SWEEP, Option, Technique


# Roberts' R_d sequences (2018): the root of x^(d+1) = x + 1 for d dimensions.
_R_ROOTS = {2: 1.32471795724474602596, 3: 1.22074408460575947536}


def r_sequence(n: int, dims: int, seed: int = 0, start: int = 0) -> np.ndarray:
    """n points in [0, 1)^dims, well stratified for any n (R_d sequence with a seeded offset); `start` skips
    the sequence's first points, so successive batches continue one sequence."""
    g = _R_ROOTS[dims]
    alpha = np.array([1.0 / g ** k for k in range(1, dims + 1)])
    offset = np.random.default_rng(seed).random(dims)
    return (offset + np.arange(start + 1, start + n + 1)[:, None] * alpha) % 1.0


def _kept_points(n: int, seed: int, batch: int, place, max_batches: int) -> np.ndarray:
    """Up to n points by rejection from successive batches of one 2-D `r_sequence`: `place` maps a batch of
    [0, 1)² points and says which to keep (the kept points stay in the sequence's order, so stratified)."""
    kept, total = [], 0
    for k in range(max_batches):
        points, keep = place(r_sequence(batch, 2, seed, start=k * batch))
        kept.append(points[keep])
        total += int(np.count_nonzero(keep))
        if total >= n:
            break
    return np.concatenate(kept)[:n]


def unit_square_samples(n: int, seed: int = 0) -> np.ndarray:
    """n points in [-1, 1]², well stratified for any n (`r_sequence`)."""
    return r_sequence(n, 2, seed) * 2.0 - 1.0


def concentric_disk(q: np.ndarray) -> np.ndarray:
    """Shirley & Chiu's area-preserving map of [-1, 1]² onto the unit disk."""
    a, b = q[:, 0], q[:, 1]
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(use_a, np.pi / 4 * (b / a), np.pi / 2 - np.pi / 4 * (a / b))
    phi = np.nan_to_num(phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def _unit_directions(u: np.ndarray) -> np.ndarray:
    """(n, 3) points uniform on the unit sphere from (n, 2) points uniform in [0, 1)² (Archimedes' z)."""
    z = 1.0 - 2.0 * u[:, 0]
    phi = 2.0 * np.pi * u[:, 1]
    ring = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1)


def sphere_surface(n: int, seed: int = 0) -> np.ndarray:
    """n points uniform over the unit sphere, stratified with `r_sequence`: a true sphere light's emitter as
    its receivers inside it see it (every direction ends on the surface)."""
    return _unit_directions(r_sequence(n, 2, seed))


def projected_disk_ball(n: int, seed: int = 0) -> np.ndarray:
    """n points in the unit ball whose projection along ANY direction is uniform over the unit disk: radial
    density ∝ 1/√(1 − r²) (its integral along a chord at distance ρ from the centre is π for every ρ). A point
    or spot light with a radius is, seen from each receiver, a disk facing it (Cycles' soft falloff, or the
    sphere's silhouette far away); points on one fixed disk would be foreshortened for receivers off its axis.
    Stratified with `r_sequence`."""
    u = r_sequence(n, 3, seed)
    direction = _unit_directions(u[:, :2])
    # r = sin ψ with CDF (ψ − sin ψ cos ψ)/(π/2); Newton steps
    target = u[:, 2] * np.pi / 2.0
    psi = np.full(n, np.pi / 4.0)
    for _ in range(30):
        f = psi - np.sin(psi) * np.cos(psi) - target
        psi = np.clip(psi - f / np.maximum(2.0 * np.sin(psi) ** 2, 1e-6), 0.0, np.pi / 2.0)
    return direction * np.sin(psi)[:, None]


def light_samples(light: Light, n: int, seed: int = 0, ball: bool = False) -> np.ndarray:
    """(n, 2) offsets in the light's local XY plane: metres, or tan of the tilt for a sun; with `ball`, (n, 3)
    points in a point or spot light's ball (`projected_disk_ball`) instead of its disk."""
    if ball and light.kind not in (AREA, SUN):
        return projected_disk_ball(n, seed) * light.radius
    q = unit_square_samples(n, seed)
    round_ = light.kind != AREA or light.shape in (DISK, ELLIPSE)
    if round_:
        q = concentric_disk(q)
    if light.kind == AREA:
        return q * np.array([light.size_x / 2.0, light.size_y / 2.0])
    if light.kind == SUN:
        # Uniform over the cone's solid angle, as Cycles samples a sun (the disk's area maps to 1 − cosθ),
        # returned as tan θ along the sample's azimuth: uniform in tan θ would crowd the rim of a wide sun.
        r = np.linalg.norm(q, axis=1)
        cos_t = np.maximum(1.0 - r * r * (1.0 - np.cos(min(light.angle / 2.0, np.pi / 2))), 1e-4)
        tan_t = np.sqrt(1.0 - cos_t * cos_t) / cos_t
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.nan_to_num(q / r[:, None]) * tan_t[:, None]
    return q * light.radius


def _fills_ball(light: Light, view, split: bool, nearest: float | None) -> bool:
    """Whether a sphere light's samples fill its ball or its disk across the view axis (a true sphere or a
    soft-falloff spot; a soft-falloff point light's always fill the ball, Averaged.visibility). A receiver θ
    off the axis sees the disk foreshortened by cos θ, the ball never; but a ball point nearer or farther
    than the centre moves the ray to a receiver at distance d by up to r/d across its disk. The view's
    widest angle (1 − cos θ) against r over the nearest receiver's distance picks the smaller error: the disk
    for a narrow view (a spot's cone), the ball for a light whose receivers surround it (a room, or any light
    seen through cube faces: every one of its views keeps the ball, and a face's axis is not the light frame's
    Z, across which the disk lies). The receivers' distance (`nearest`, LightContext.nearest_receiver; the
    view's near depth where it is unknown), not the view's near depth alone: casters around the light pull
    that to nothing, and the disk then cut the penumbra on a wall 74° off the axis to cos 74° of its width
    (fuzz 24000: a monkey 0.44 m from a 0.06 m light inside a room; mae_shadow 0.057 at 128², 0.022 with the
    ball). The nearest receiver is never nearer than the view's near plane, so the larger of the two decides.
    A true sphere's ball has no such error: the ray to any point of the ball ends where it enters the sphere,
    and the casters inside it stay out of the maps (_sphere_clip), so every ray meets Cycles' emitter. Its
    disk, besides the foreshortening, misses the sphere's limb: from distance d the sphere spans asin(r/d)
    about its centre, the disk atan(r/d). The disk stays only where both errors are within TRUE_SPHERE_DISK
    (a narrow spot far from its receivers, whose cone region keeps the samples where they count)."""
    if split or view.face is not None:
        return True
    t = float(np.max(np.abs(view.window)))
    foreshortening = 1.0 - 1.0 / float(np.hypot(1.0, t))
    distance = max(float(view.near), nearest if nearest is not None else 0.0)
    if not light.use_soft_falloff:
        x = min(light.radius / max(distance, 1e-9), 1.0)
        silhouette = 1.0 - float(np.arctan(x) / np.arcsin(x)) if x > 0.0 else 0.0
        return max(foreshortening, silhouette) > TRUE_SPHERE_DISK
    return foreshortening > light.radius / max(distance, 1e-9)


# The largest error _fills_ball accepts from a true sphere's disk (its foreshortening, its missed limb): a view
# within ±8° of the axis, a sphere under 0.14 of its nearest receiver's distance.
TRUE_SPHERE_DISK = 0.01


# A soft-falloff light with receivers nearer than this many radii serves them from beyond their disks
# (SIDE_BEYOND_DISK) even with nothing inside its ball: the ball points on a receiver's side of the centre see
# it almost edge-on. A 1 m light over a floor with a box beside it (64², Cycles 1024 spp), all samples of the
# ball against those beyond the disk: 1.3 m up (r/d 0.77) 0.025 -> 0.012, 2 m up 0.010 -> 0.008; a 0.6 m
# light 1.3 m up 0.019 -> 0.011; a 0.3 m one the same (0.0112, 0.0115).
NEAR_BALL = 2.5


# Surfaces peeled behind each sample map where a soft-falloff light's ball holds geometry: what lies between
# a sample and the disk a receiver's ray ends on (a wall the ball reaches through, an object's two faces) is
# looked past. One layer against two (64², REFERENCE frame on llvmpipe): fuzz 27009 0.0198 / 0.0173 (7.2 /
# 11.7 s), 28000 0.0260 / 0.0202 (6.9 / 11.5 s), 27014 0.0066 both (39 / 75 s).
PEELED_LAYERS = 2


def _ball_holds_geometry(frame, lc) -> bool:
    """Whether some triangle may lie inside a point or spot light's ball (the scene's clearance from its
    centre, SceneSnapshot.clearance, or where that is not known, the receivers' and casters' boxes): then
    shadow rays that end on Cycles' disk facing each receiver and rays that end at ball samples meet
    different surfaces, and its samples serve each receiver from beyond that disk (SIDE_BEYOND_DISK)."""
    light = lc.light
    clearance = frame.geometry.light_clearances().get(light.name)
    if clearance is not None:
        return clearance < light.radius
    return any(_box_distance(light.position, b) < light.radius for b in (lc.receivers, lc.casters) if b is not None)


def _box_distance(point, box) -> float:
    """Distance from `point` to the world box (lo, hi): 0 inside it."""
    c = np.asarray(point, float)
    return float(np.linalg.norm(np.clip(c, np.asarray(box[0], float), np.asarray(box[1], float)) - c))


CONE_SAMPLES_MAX = 16         # cone_sample_count: at most this many times the setting's samples


def cone_sample_count(light: Light, n: int, receivers, region_area: float | None = None) -> int:
    """Samples to draw over a spot light with a radius so that about `n` of them light each receiver. Cycles
    applies the cone per ray (kernel/light/spot.h), so a receiver at depth d below the light receives light
    only through the cone's footprint on the emitter, an ellipse of half axes d·tanβ·(scale x or y / scale z):
    where that is smaller than the area the samples are drawn over (`region_area`, the disk by default), only
    its share of the samples carries weight at the receiver, and the average of so few hard maps shows their
    steps (fuzz 36: a 3.1 m spot 5 m away, 64 samples 0.052, 256 0.019 against a noise floor of 0.019). The
    nearest lit receiver (the box of the pixels the light reaches) sets the share; the count grows by its
    inverse, up to CONE_SAMPLES_MAX times `n`."""
    if light.kind != SPOT or light.is_delta or light.radius <= 0.0 or n <= 1:
        return n
    d = _box_distance(light.position, receivers)
    tx, ty = spot_cone_tans(light)
    footprint = np.pi * d * d * tx * ty
    area = np.pi * light.radius ** 2 if region_area is None else region_area
    share = min(1.0, footprint / max(area, 1e-30))
    return int(min(np.ceil(n / max(share, 1e-12)), n * CONE_SAMPLES_MAX))


def cone_region(light: Light, receivers) -> tuple | None:
    """(x0, x1, y0, y1), metres in the light's XY plane: the part of a spot's disk through which the cone
    lets any receiver of the box see it, or None where that is all of it or undefined (a receiver level with
    or behind the light). A ray from disk point (x, y, 0) reaches receiver (px, py, pz) inside the cone only if
    |px − x| ≤ −pz·tanβx and |py − y| ≤ −pz·tanβy (the cone's box); both bounds are linear in the receiver,
    so the box's corners give their extremes."""
    if light.kind != SPOT or light.is_delta or light.radius <= 0.0:
        return None
    corners = lightview.box_corners(*(np.asarray(b, float) for b in receivers))
    local = lightview.to_local(np.linalg.inv(np.asarray(light.matrix, float)), corners)
    depth = -local[:, 2]
    if np.any(depth <= 0.0):
        return None
    tx, ty = spot_cone_tans(light)
    r = float(light.radius)
    box = (max(float(np.min(local[:, 0] - depth * tx)), -r), min(float(np.max(local[:, 0] + depth * tx)), r),
           max(float(np.min(local[:, 1] - depth * ty)), -r), min(float(np.max(local[:, 1] + depth * ty)), r))
    if box[0] >= box[1] or box[2] >= box[3] or box == (-r, r, -r, r):
        return None
    return box


def region_disk_samples(n: int, box, radius: float, seed: int = 0) -> np.ndarray:
    """n points uniform over the part of the disk of `radius` inside `box` (x0, x1, y0, y1): `r_sequence`
    points of the box, those outside the disk left out (the sequence stays stratified under the cut)."""
    lo, span = np.array([box[0], box[2]]), np.array([box[1] - box[0], box[3] - box[2]])

    def place(u):
        q = lo + u * span
        return q, np.einsum("ij,ij->i", q, q) <= radius * radius
    return _kept_points(n, seed, max(4 * n, 256), place, max_batches=65)


def disk_share(box, radius: float, seed: int = 0) -> float:
    """Share of `box` (x0, x1, y0, y1) inside the disk of `radius`, from 4096 `r_sequence` points."""
    q = np.array([box[0], box[2]]) + r_sequence(4096, 2, seed) * np.array([box[1] - box[0], box[3] - box[2]])
    return float(np.mean(np.einsum("ij,ij->i", q, q) <= radius * radius))


def _sphere_clip(light: Light, receivers) -> tuple:
    """(clip sphere or None, whether any receiver may be inside) for a true sphere light and the receivers'
    box. Cycles' shadow rays towards a true sphere end on its surface: for a receiver outside it nothing inside
    the sphere occludes, so its maps leave the casters inside out (frame.render_depth_layers' clip); from a
    receiver inside it every direction ends on the surface, so those sample the surface with every caster.
    Measured: tests/test_enclosing_lights.py."""
    lo, hi = (np.asarray(b, float) for b in receivers)
    c, r = np.asarray(light.position, float), float(light.radius)
    farthest = np.linalg.norm(np.maximum(np.abs(lo - c), np.abs(hi - c)))
    return ((c, r) if farthest > r else None), _box_distance(c, receivers) <= r


def _inside_receivers(light: Light, receivers, points) -> tuple:
    """The receivers' box cut to the sphere light's box, and the points (world, N × 3, or None) inside its
    sphere: what the samples on its surface serve (SIDE_INSIDE)."""
    c, r = np.asarray(light.position, float), float(light.radius)
    lo, hi = (np.asarray(b, float) for b in receivers)
    lo, hi = np.maximum(lo, c - r), np.minimum(hi, c + r)
    if points is not None:
        points = np.asarray(points, float)
        points = points[np.einsum("ij,ij->i", points - c, points - c) <= r * r * (1.0 + 1e-6)]
        if not len(points):
            points = None
    return (lo, np.maximum(hi, lo)), points


# An area light wider than this many times its distance to the receivers' centre gets solid-angle samples too
# (`near_area_samples`): uniform points then put only a handful where a receiver's weights are.
NEAR_AREA_RATIO = 4.0
UNIFORM_SHARE = 0.25    # of those samples uniform over the light: no weight exceeds 1/UNIFORM_SHARE


def _inside_shape(light: Light, xy: np.ndarray) -> np.ndarray:
    """Which light-plane points (n, 2), metres from the centre, lie on the area light."""
    u, v = xy[:, 0] / (light.size_x / 2.0), xy[:, 1] / (light.size_y / 2.0)
    if light.shape in (DISK, ELLIPSE):
        return u * u + v * v <= 1.0
    return (np.abs(u) <= 1.0) & (np.abs(v) <= 1.0)


def near_area_samples(light: Light, n: int, receivers, seed: int = 0):
    """(offsets (n, 2), relative weights (n,)) for an area light much wider than its distance h to the
    receivers' centre c, or None for any other light. Uniform points over a 40 m light 2 m away put about one
    sample where a receiver's cosine-over-d² weights are (fuzz seed 99: mae_shadow 0.13 at 64 samples, 0.015
    at 1024). A quarter of the samples (UNIFORM_SHARE) stay uniform over the light, the rest follow the solid
    angle seen from c (density h / (2π (h² + ρ²)^{3/2}) around c's foot point, kept to the light's shape);
    each carries 1/pdf of that mixture (Veach's balance heuristic, thesis §9.2), so the weighted mean stays
    consistent for every receiver, and the uniform share bounds the weights where c's density is low."""
    if light.kind != AREA or n < 2 or light.area <= 0.0:
        return None
    lo, hi = (np.asarray(b, float) for b in receivers)
    m = np.asarray(light.matrix, float)
    rel = (lo + hi) / 2.0 - m[:3, 3]
    h = -float(np.dot(rel, m[:3, 2]))               # the light emits along its -Z
    if h <= 0.0 or max(light.size_x, light.size_y) < NEAR_AREA_RATIO * h:
        return None
    foot = np.array([np.dot(rel, m[:3, 0]), np.dot(rel, m[:3, 1])])
    half = np.array([light.size_x, light.size_y]) / 2.0
    rho_max = float(np.linalg.norm(np.abs(foot) + half))
    mass_max = 1.0 - h / np.hypot(h, rho_max)        # the disk of radius rho_max's share of the half-space
    n_uniform = max(1, int(round(n * UNIFORM_SHARE)))
    share = n_uniform / n
    uniform = light_samples(light, n_uniform, seed)

    def warp(q):        # [0, 1)² → the disk of radius rho_max, by the solid angle seen from c
        rho = h * np.sqrt(np.maximum(1.0 / (1.0 - q[:, 0] * mass_max) ** 2 - 1.0, 0.0))
        return foot + rho[:, None] * np.stack([np.cos(2 * np.pi * q[:, 1]), np.sin(2 * np.pi * q[:, 1])], axis=1)

    def place(q):
        xy = warp(q)
        return xy, _inside_shape(light, xy)
    warped = _kept_points(n - n_uniform, seed + 1, 4 * n, place, max_batches=16)
    if len(warped) < n - n_uniform:
        return None

    def density(xy):
        return h / (2.0 * np.pi * (h * h + np.sum((xy - foot) ** 2, axis=1)) ** 1.5)
    # The warped density's mass on the light's shape (its normalisation there): the disk's mass times the share
    # of 2^16 warped points that land on the shape (a grid over the light would miss the peak of a small h).
    total = mass_max * float(_inside_shape(light, warp(r_sequence(1 << 16, 2, seed + 2))).mean())
    offsets = np.concatenate([uniform, warped])
    pdf = share / light.area + (1.0 - share) * density(offsets) / total
    return offsets, (1.0 / light.area) / pdf       # 1 where the mixture is uniform


EFFECTIVE_SHARE = 0.25      # area_sample_count: the share of the samples that must count at every receiver


def effective_share(light: Light, offsets: np.ndarray, relative, probes: np.ndarray) -> float:
    """The smallest share of an area light's samples (offsets (n, 2), relative weights or None) that carries
    weight at any of the receiver `probes` (world, (k, 3)): Kish's effective count (Σw)²/Σw² over n, with each
    sample's unoccluded weight cosθ_light·cosθ_receiver/d² for a receiver facing the light. 1 for equal
    weights; probes behind the light's plane are left out."""
    m = np.asarray(light.matrix, float)
    world = m[:3, 3] + offsets[:, :1] * m[:3, 0] + offsets[:, 1:2] * m[:3, 1]
    share = 1.0
    for q in probes:
        d = world - q
        d2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
        cos = np.maximum(d @ m[:3, 2], 0.0) / np.sqrt(d2)      # both cosines, for a receiver facing the light
        w = cos * cos / d2 * (1.0 if relative is None else relative)
        if w.sum() > 0.0:
            share = min(share, float(w.sum() ** 2 / np.dot(w, w)) / len(w))
    return share


def area_sample_count(light: Light, n: int, share: float) -> int:
    """Samples to draw over an area light so that at least EFFECTIVE_SHARE of `n` count at every receiver,
    given the `share` (effective_share) that n samples leave at the worst one: a light much wider than its
    distance weighs a receiver far from the others by the few samples above it (fuzz 9034: a 79 × 14 m light
    4.5 m away, 64 samples left one effective sample at a receiver box corner; mae_shadow 0.043, 256 samples
    0.020). At most CONE_SAMPLES_MAX times `n`."""
    if share >= EFFECTIVE_SHARE or n <= 1:
        return n
    return int(min(np.ceil(n * EFFECTIVE_SHARE / max(share, 1e-12)), n * CONE_SAMPLES_MAX))


# more_samples: the effective samples (Kish's (Σw)²/Σw², per pixel) a light's penumbra must average, as a share
# of the setting's count. At 256 samples the built-in scenes' penumbrae average 0.70 (city) to 1.0 of it, and
# those are where 256 was found enough (README, REFERENCE); half of it leaves them alone and lifts the sets
# whose receivers each weigh a small part of the light (seeds 29263-29362: 16 of their lights, most of them
# suns wider than 100°, at 0.12-0.49).
EFFECTIVE_TARGET = 0.5
PENUMBRA_LEVELS = (1e-3, 1.0 - 1e-3)     # a pixel's visibility strictly between these: in the penumbra


def more_samples(sums: np.ndarray, square_weights: np.ndarray, served: np.ndarray, n_done: int, n: int) -> int:
    """How many samples to add to a set of `n_done` so that its penumbra averages as well as n·EFFECTIVE_TARGET
    equal samples would, from accumulate.comp's per-pixel sums (H, W, 4: Σw·v, Σw, Σv, count) and Σw², over the
    pixels the set `served`. A pixel's estimate rests on the samples it weighs: a receiver that sees a cap of
    the light above its horizon (a soft-falloff ball whose centre lies under the floor, a sun wider than its
    sky) weighs few, and the average of so few hard maps shows their steps (fuzz 30243: a 1.56 m soft-falloff
    light 0.1 m under the tilted floor, 51 effective of 512 samples; REFERENCE mae_shadow 0.051 at 256 samples,
    0.023 at 1024). A pixel's error from its samples is taken to go as 1/√(effective count) (the stratified
    sequence does better, but the ratio between counts is what matters here), and mae_shadow sees its mean
    over the penumbra pixels: the count grows until that mean matches the target's, to at most
    CONE_SAMPLES_MAX·n in all. Pixels fully lit or in umbra are left out: every sample agrees there."""
    sw, sq = sums[..., 1], square_weights
    on = served & (sw > 0.0) & (sq > 0.0)
    v = sums[..., 0][on] / sw[on]
    penumbra = (v > PENUMBRA_LEVELS[0]) & (v < PENUMBRA_LEVELS[1])
    if not penumbra.any():
        return 0
    effective = sw[on][penumbra] ** 2 / sq[on][penumbra]
    spread = float(np.mean(1.0 / np.sqrt(np.maximum(effective, 1.0))))
    wanted = n_done * EFFECTIVE_TARGET * n * spread * spread
    if wanted <= n_done:
        return 0
    return max(int(min(np.ceil(wanted), CONE_SAMPLES_MAX * n)) - n_done, 0)


def _probes(lc, count: int = 256) -> np.ndarray:
    """Receiver points to judge sample weights at: the view's lit points where read back (every k-th, at
    most `count`), else its receivers' box corners and centre."""
    if lc.receiver_points is not None and len(lc.receiver_points):
        pts = np.asarray(lc.receiver_points, float)
        return pts[::max(1, len(pts) // count)]
    lo, hi = (np.asarray(b, float) for b in lc.receivers)
    return np.concatenate([lightview.box_corners(lo, hi), [(lo + hi) / 2.0]])


def tilted_sun(light: Light, offset: np.ndarray) -> Light:
    """The sun turned so that it shines along a direction of its disk: -Z + offset·(X, Y), normalised."""
    from dataclasses import replace
    m = np.array(light.matrix, float)
    forward = -m[:3, 2] + offset[0] * m[:3, 0] + offset[1] * m[:3, 1]
    forward /= np.linalg.norm(forward)
    x = m[:3, 0] - forward * np.dot(m[:3, 0], forward)
    x /= np.linalg.norm(x)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, np.cross(-forward, x), -forward
    return replace(light, matrix=m)


def light_extent(light: Light) -> float:
    """The light's smallest half extent (metres; a sun's tan of its half angle; 0 for a point-like light):
    accumulate.comp's measure of how wide a caster's penumbra is against a texel."""
    if light.is_delta:
        return 0.0
    extent = float(min(light_half_extent(light)))
    # a sun wider than 178° is held at tan 89° here, short of the shading clamp light_half_extent draws at
    return min(extent, float(np.tan(np.radians(89.0)))) if light.kind == SUN else extent


class AveragedMaps(Technique):
    identifier = "REFERENCE"
    label = "Averaged shadow maps"
    description = "Average of N hard shadow maps from points on the light: slow ground truth"
    needs = ()
    fits_sample_views = True
    # The identifier stays REFERENCE (stored in .blend files and scripts); its settings say what it does.
    options = (
        # 256: the fewest that keep its error under Cycles-64's on the built-in scenes (README, REFERENCE)
        Option("averaged_light_samples", 256, "Light Samples", "Hard shadow maps averaged per light",
               min=1, max=4096),
        Option("averaged_weighted", True, "Weighted",
               "Weight each light sample by its unoccluded contribution at the pixel"),
        # Off by default for its cost: the second layered pass per batch took REFERENCE's frame on `suzanne` at
        # 128² from 1.8 s to 5.3 s on llvmpipe (shadow_map 1.45 -> 4.8 s). On: fuzz 1103 (Suzanne's concave
        # creases at grazing light) 0.107 -> 0.051 against its bound 0.078; fuzz 30740-30779 0/40 over either
        # way, error x shadow pixels 81.4 -> 81.1, 30749 0.0015 -> 0.015 and 30758 0.0061 -> 0.0135 (bounds 0.13
        # and 0.10: faces at n.l 0.01 whose texel holds a neighbour the ray itself passes).
        Option("averaged_facets", False, "Facet Test",
               "Where the depth bias leaves a receiver lit, test it against the plane of the triangle the map "
               "holds there, so that a crease's far face within the bias still shadows it; about 3x the time of "
               "the sample maps (one more layered pass per batch)"),
    )
    reads_shared = ("seed", "early_skip")
    coarse = {"averaged_light_samples": 8}
    sweep = MAP_SIZE_SWEEP + tuple({"averaged_light_samples": n} for n in (16, 64, 1024))

    def needs_for(self, settings) -> tuple:
        # The classes come from the light centre's depth map, one map more than the N samples render.
        return (need(LIT_UMBRA, narrow=True, texel_ratio=SKIP_TEXEL_RATIO),) if settings.early_skip else ()

    def visibility(self, frame, lc, out):
        s, light = frame.settings, lc.light
        n = 1 if light.is_delta else int(s.option("averaged_light_samples"))
        soft_disk = light.kind in (POINT, SPOT) and light.radius > 0.0 and light.use_soft_falloff
        holds_geometry = soft_disk and _ball_holds_geometry(frame, lc)
        beyond_disk = holds_geometry or (soft_disk and lc.nearest_receiver is not None and
                                         lc.nearest_receiver < NEAR_BALL * light.radius)
        # A soft-falloff point light's samples always fill the ball, whose weights are exact in every
        # direction (accumulate.comp soft_disk_weight); the disk across the view's axis is foreshortened for
        # receivers off it (a 1 m light 3 m over a box's penumbra 0.9 m off the axis: 0.051 on the disk,
        # 0.0105 in the ball). A spot keeps the choice, for its samples where the cone lets receivers see them.
        ball = light.kind in (POINT, SPOT) and light.radius > 0.0 and \
            (beyond_disk or (soft_disk and light.kind == POINT) or
             _fills_ball(light, lc.view, lc.split, lc.nearest_receiver))
        # A spot's samples on its disk lie where the cone lets some receiver see it, as many as keep ~n in
        # each receiver's footprint (cone_region, cone_sample_count)
        region = None if ball else cone_region(light, lc.receivers)
        area = None
        if region is not None:
            area = (region[1] - region[0]) * (region[3] - region[2]) * disk_share(region, light.radius, s.seed)
            if area <= 0.0:
                region, area = None, None
        n_light = cone_sample_count(light, n, lc.receivers, area)
        if n_light != n or region is not None:
            frame.count(cone_samples=n_light, cone_regions=int(region is not None))
        if light.is_delta:
            offsets = np.zeros((1, 2))
        elif region is not None and len(samples_in := region_disk_samples(n_light, region, light.radius, s.seed)):
            offsets = samples_in
        else:
            offsets = light_samples(light, n_light, s.seed, ball)
        relative = None             # each sample's weight against a uniform one (near_area_samples)
        near = near_area_samples(light, n_light, lc.receivers, s.seed) if s.option("averaged_weighted") else None
        if near is not None:
            offsets, relative = near
        if light.kind == AREA and s.option("averaged_weighted") and n_light > 1:
            # as many samples as keep a quarter of the setting's count effective at every receiver
            more = area_sample_count(light, n_light, effective_share(light, offsets, relative, _probes(lc)))
            if more != n_light:
                n_light = more
                frame.count(area_samples=n_light)
                near = near_area_samples(light, n_light, lc.receivers, s.seed)
                offsets, relative = near if near is not None else (light_samples(light, n_light, s.seed), None)
        sums = frame.texture((frame.width, frame.height), 4)        # zero-filled
        square_weights = frame.texture((frame.width, frame.height), 1)
        weight_mode = WEIGHT_NONE
        if s.option("averaged_weighted"):
            weight_mode = WEIGHT_AREA if light.kind == AREA else WEIGHT_SUN if light.kind == SUN else WEIGHT_SPHERE
        spot = spot_uniforms(light)
        spot["u_light_extent"] = light_extent(light)
        true_sphere = light.kind in (POINT, SPOT) and light.radius > 0.0 and not light.use_soft_falloff
        spot["u_sphere_inside"] = (*map(float, light.position), light.radius ** 2 if true_sphere else -1.0)
        spot["u_soft_disk"] = (0.0, 0.0, 0.0, -1.0)
        # Sample sets: every receiver from `offsets`, except for a true sphere, whose receivers outside it
        # read maps without the casters inside it and whose receivers inside it sample its surface. The last
        # entry gives a set's first k offsets of its sequence, for more_samples (None: the set's points are
        # not the start of one sequence, or carry weights of their own).
        sequence = None
        if not light.is_delta and relative is None and region is None:
            def sequence(k):
                return light_samples(light, k, s.seed, ball)
        sets = [(offsets, relative, None, SIDE_ALL, sequence)]
        if true_sphere:
            clip, inside = _sphere_clip(light, lc.receivers)

            def surface(k):
                return sphere_surface(k, s.seed) * light.radius
            sets = ([(offsets, relative, clip, SIDE_OUTSIDE, sequence)] if clip else []) + \
                   ([(surface(n), None, None, SIDE_INSIDE, surface)] if inside else [])
        elif beyond_disk:
            # each receiver takes only the samples beyond its facing disk, about half of them: twice as many,
            # within the spot's cap (cone_sample_count: a spot around its receivers has it at 16× already)
            n_beyond = min(2 * n_light, max(n_light, n * CONE_SAMPLES_MAX))

            def ball_points(k):
                return light_samples(light, k, s.seed, ball=True)
            sets = [(ball_points(n_beyond), None, None, SIDE_BEYOND_DISK, ball_points)]
            frame.count(beyond_disk_samples=n_beyond)
        total = sum(len(o) for o, *_ in sets)
        # The classes come from the centre's map with every caster, whose rays end at the centre: not those of
        # a true sphere's sets, nor of rays that end on a disk through geometry.
        classes = lc.structures.get(LIT_UMBRA) if not (true_sphere or holds_geometry) else None
        skip = {}, {"EARLY_SKIP": 0}
        done = 0

        def accumulate(set_offsets, set_relative, clip, side, first: int = 0):
            """Render the maps of one set's samples and add them to the sums; `first` > 0: samples that
            continue a set already accumulated (from that index of its sequence), under its early-skip decision."""
            nonlocal classes, skip, done
            more = first > 0
            samples = self._samples(frame, lc, set_offsets, set_relative,
                                    size=delta_map_size(lc.view.size, int(s.option("averaged_light_samples")))
                                    if light.is_delta else None, inward=side == SIDE_INSIDE, first=first)
            if soft_disk:
                # accumulate.comp soft_disk_weight: the axis of the disk the offsets lie on (the sample views'
                # Z: each keeps the light's frame), none when they fill the ball
                axis = np.zeros(3)
                if not ball:
                    axis = np.asarray(samples[0][0].view, float)[2, :3]
                    axis = axis / max(float(np.linalg.norm(axis)), 1e-30)
                spot["u_soft_disk"] = (*map(float, axis), float(light.radius))
            # Pixels proven lit or umbra skip every sample's look-up; resolve writes their 1 or 0, which is
            # what the weighted mean of N equal visibilities is, whatever the weights. The classes allow for
            # sample maps whose texels are up to SKIP_TEXEL_RATIO times the centre view's (bias and offset).
            if classes is not None and not more:
                ratio = max(max(v.texel_size()) for v, *_ in samples) / max(max(lc.view.texel_size()), 1e-30)
                if ratio > SKIP_TEXEL_RATIO:
                    classes = None
                    frame.count(skip_views_unused=1)
            skip = ({"u_classes": classes.classes} if classes else {}), {"EARLY_SKIP": int(classes is not None)}
            # Batches of maps rendered in one layered pass and accumulated in one dispatch (in sample order).
            largest = max(v.width * v.height for v, *_ in samples)
            # the maps, and where geometry lies inside the ball, the surfaces peeled behind them
            layers = 1 + PEELED_LAYERS if side == SIDE_BEYOND_DISK and holds_geometry else 1
            facets = bool(s.option("averaged_facets"))
            # bytes per texel of a sample: its R32F depth layers, and the RGBA16F facet normals
            batch = int(min(MAX_DEPTH_LAYERS, max(1, BATCH_BYTES // ((4 * layers + 8 * facets) * largest))))
            for first in range(0, len(samples), batch):
                frame.progress.check()
                part = samples[first:first + batch]
                with frame.timings.stage("shadow_map"):
                    views = [v for v, *_ in part]
                    maps = [frame.render_depth_layers(views, clip_sphere=clip)]
                    while len(maps) < layers:
                        maps.append(frame.render_depth_layers(views, behind=maps[-1]))
                    # the batch's layered arrays, by the sampler accumulate.comp reads each through
                    arrays = {"u_depth_maps": maps[0],
                              **{f"u_depth_maps_{k}": m for k, m in enumerate(maps[1:], 1)}}
                    if facets:
                        arrays["u_facet_maps"] = frame.render_facet_layers(views, maps[0], clip_sphere=clip)
                with frame.timings.stage("visibility"):
                    records = frame.buffer(_sample_records(part))
                    frame.dispatch("averaged/accumulate.comp", {
                        **frame.bias_uniforms, "u_count": len(part), "u_weight_mode": weight_mode,
                        "u_side": side, **spot},
                        samplers={"g_irradiance": lc.irradiance, **arrays, **skip[0]},
                        images={0: sums, 2: square_weights}, buffers={1: records},
                        defines={**skip[1], "PEELED": layers - 1, "FACETS": int(facets)})
                for array in arrays.values():
                    frame.give_back(array)      # the next batch draws into the same arrays
                frame.give_back(records)
                done += len(part)
                frame.progress.step(done / total, f"{light.name}: sample {done}/{total}")

        # The pixels a set served are those whose sample count it raised; before the first set every count is 0,
        # so the sums are read back before a set only where an earlier one has added to them.
        counted = False
        for set_offsets, set_relative, clip, side, set_sequence in sets:
            before = frame.read(sums)[..., 3] if set_sequence is not None and counted else 0.0
            accumulate(set_offsets, set_relative, clip, side)
            counted = True
            if set_sequence is None:
                continue
            after = frame.read(sums)
            extra = more_samples(after, frame.read(square_weights)[..., 0], after[..., 3] > before,
                                 len(set_offsets), n)
            if extra:
                frame.count(more_samples=extra)
                total += extra
                accumulate(set_sequence(len(set_offsets) + extra)[len(set_offsets):], None, clip, side,
                           first=len(set_offsets))
        frame.dispatch("averaged/resolve.comp", samplers={"u_sums": sums, **skip[0]}, images={0: out},
                       defines=skip[1])

    @staticmethod
    def _samples(frame, lc, offsets, relative=None, size=None, inward=False, first: int = 0) -> list:
        """(view, sample position, emission axis, relative weight) per light sample: each map's view keeps the
        light's axes and is refitted from the sample point (a sun's turned towards its sample direction), its
        texel grid shifted by the sample's `grid_shift` (`first`: the index of the first offset in its set's
        sequence); `size` (texels) instead of the centre view's. `inward`: the offsets lie on a true sphere's
        surface and serve the receivers inside it, each map looking from its point towards the centre."""
        light = lc.light
        size = lc.view.size if size is None else size
        samples = []
        receivers = lc.receivers
        # The lit points, where known, bound each sample's window tighter than their box, whose corners can
        # straddle a sample's plane where no lit point does (lightview.fit); their grid cells' corners, so
        # that N fits do not each project every pixel.
        points = lc.receiver_points
        if inward:
            receivers, points = _inside_receivers(light, receivers, points)
        points = None if points is None else lightview.cell_corners(points)
        # What a sample whose map cannot hold the receivers looks at instead (_facing_receivers), in the frame
        # lightview.fit puts the offsets in: the centre of the receivers (their points' box where known).
        lo, hi = receivers if points is None else (points.min(axis=0), points.max(axis=0))
        aim = (np.asarray(lo, float) + np.asarray(hi, float)) / 2.0
        world_to_light = lc.view.frame if lc.view.frame is not None else \
            lightview.light_frame(light, (np.asarray(receivers[0], float) + np.asarray(receivers[1], float)) / 2.0)
        for i, offset in enumerate(offsets):
            if i % 64 == 0:
                frame.progress.check()      # thousands of views take a while to fit: stay cancellable
            emit = light.direction
            if light.kind == SUN:
                tilted = tilted_sun(light, offset)
                view = lightview.fit(tilted, lc.receivers, lc.casters, size, receiver_points=points)
                sample_world, emit = light.position, tilted.direction
            else:
                local = np.array([offset[0], offset[1], offset[2] if len(offset) > 2 else 0.0])
                # A cube face keeps its turn: every sample's map looks the way the face looks. A point of a
                # sphere's surface sees the receivers inside the sphere in the half space towards its centre,
                # which its map holds only looking that way (the light's axis would leave out those behind
                # it, and a receiver then lost the samples below it: too bright).
                face = lc.view.face
                if inward:      # (the offset and the turn are both in the light's frame)
                    face = lightview.face_rotation(-local / max(float(np.linalg.norm(local)), 1e-30))
                view = lightview.fit(light, receivers, lc.casters, size, origin_local=local,
                                     frame=lc.view.frame, face=face, receiver_points=points)
                sample_world = (np.linalg.inv(view.view) @ np.array([0.0, 0.0, 0.0, 1.0]))[:3]
                if view.clamped and not inward:
                    # Receivers more than 80° off the light's axis as this point sees them (a point of a huge
                    # emitter far from them sees them almost in its own plane) fall off a map that keeps the
                    # axis, and off the map counts as lit: that point's map looks at them instead (fuzz 27026,
                    # a 187 m ellipse light: REFERENCE 0.85, every sample 50 m out lighting a receiver that
                    # a cone shadows). Kept where it still cannot hold them.
                    view = _facing_receivers(light, world_to_light, local, sample_world, aim, receivers,
                                             lc.casters, size, points) or view
            if not light.is_delta:
                view = shifted_grid(view, grid_shift(first + i))
            samples.append((view, sample_world, emit, 1.0 if relative is None else float(relative[i])))
        return samples


def grid_shift(index: int) -> np.ndarray:
    """The sub-texel shift (x, y in [-1/2, 1/2) texels) of sample `index`'s map grid: the Halton point of
    bases 2 and 3, which shares no stratification with the light's R_d offsets. Where a light's samples lie
    closer together than a texel seen from its casters (a 1 cm light 13 m from the floor's edge whose shadow
    falls on a wall 20 m away, fuzz 30544), every map put a hard edge on the same texel boundary, up to half a
    texel from Cycles' edge, and their average kept that error; over shifted grids it becomes an even blur of
    one texel about the true edge. The first sample's shift is 0."""
    def radical_inverse(k: int, base: int) -> float:
        value, scale = 0.0, 1.0 / base
        while k:
            value, k, scale = value + (k % base) * scale, k // base, scale / base
        return value
    k = index + 1
    point = np.array([radical_inverse(k, 2), radical_inverse(k, 3)]) - np.array([0.5, 1.0 / 3.0])
    return (point + 0.5) % 1.0 - 0.5


def shifted_grid(view, shift) -> "lightview.LightView":
    """`view` with its texel grid moved by `shift` texels (x, y): its window, one texel wider on every side so
    that it still covers the whole of the old one, at the same texel size."""
    tx, ty = view.texel_size()
    x0, x1, y0, y1 = view.window
    sx, sy = float(shift[0]) * tx, float(shift[1]) * ty
    return lightview.sub_view(view, (x0 - tx + sx, x1 + tx + sx, y0 - ty + sy, y1 + ty + sy),
                              view.width + 2, view.height + 2)


def _facing_receivers(light: Light, world_to_light, local, sample_world, aim, receivers, casters, size, points):
    """A view from the light-frame point `local` (world `sample_world`) turned to look at the world point
    `aim`, or None when that view too is clamped."""
    towards = np.asarray(world_to_light, float)[:3, :3] @ (aim - np.asarray(sample_world, float))
    length = float(np.linalg.norm(towards))
    if length <= 0.0:
        return None
    turned = lightview.fit(light, receivers, casters, size, origin_local=local, frame=world_to_light,
                           face=lightview.face_rotation(towards / length), receiver_points=points)
    return None if turned.clamped else turned


def delta_map_size(size: int, samples: int) -> int:
    """A light without extent has one sample map, where N samples of a light with extent have N: it takes
    up to √N times the texels along each side instead (16× the texels at most, and no side past DELTA_MAP_MAX
    unless the setting's own size already is). Its hard edges then fall where Cycles puts them to a quarter
    texel of the setting's map: fuzz 1027, a point light 0.8 m over a 9 m ortho view, 0.039 at 1024² against
    0.0035 at 4096²."""
    grow = max(1, min(4, int(np.sqrt(max(samples, 1)))))
    return int(min(size * grow, max(size, DELTA_MAP_MAX)))


DELTA_MAP_MAX = 4096            # texels along a side of a delta light's one map (delta_map_size)
BATCH_BYTES = 64 << 20          # at most this much texture array per batch
SKIP_TEXEL_RATIO = 2.0          # early skip: the largest sample-map texel allowed, in centre-view texels


def _sample_records(part) -> bytes:
    """averaged/accumulate.comp's Sample structs (std430, 144 bytes each); size.z: the view is clamped."""
    rec = np.zeros((len(part), 36), np.float32)
    for k, (view, position, emit, relative) in enumerate(part):
        u = view.uniforms()
        rec[k, 0:16] = u["u_light_view"]
        rec[k, 16:20] = u["u_light_window"]
        rec[k, 20:24] = (*u["u_light_depth_range"], u["u_texel_tan"], u["u_light_ortho"])
        rec[k, 24:27] = np.array((*u["u_map_size"], int(view.clamped)), np.int32).view(np.float32)
        rec[k, 28:31], rec[k, 32:35], rec[k, 35] = position, emit, relative
    return rec.tobytes()
