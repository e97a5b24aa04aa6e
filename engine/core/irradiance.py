"""Reference (numpy) unoccluded irradiance of one Blender light, matching Cycles (Blender 5.0).

`irradiance(light, points, normals)` returns E(x) in W/m² per RGB channel for a Lambertian receiver:
Cycles' diffuse radiance leaving x is albedo/π · E(x) (direct light only, no shadows).

Every light is treated as a polygon of constant radiance L seen from x, integrated with Lambert's
formula after clipping the polygon to the receiver's upper hemisphere (n·v > 0):

    E = L/2 · Σ_i acos(v̂_i·v̂_{i+1}) · n·normalize(v_i × v_{i+1})

with the vertices v_i (relative to x) wound counter-clockwise about the axis pointing from x towards
the light (so the sum is positive). Round shapes are regular N-gons whose area equals the ellipse's.

Conventions, all measured against Cycles 5.0 (see tests/test_irradiance_cycles.py):
  AREA   L = P / (π·A)   one-sided (emits towards local -Z only), Lambertian; A = world area with the
         object scale applied (size·scale_x × size_y·scale_y, ×π/4 for DISK/ELLIPSE).
  POINT  r = 0: I = P / (4π) W/sr, E = I·cosθ / d².  r > 0: emitter radiance L = P / (π · 4πr²)
         (so I = P/(4π) far away). The radius is NOT scaled by the object scale.
  SPOT   as POINT, times the cone attenuation of `spot_attenuation` (no extra cosine); with r > 0
         Cycles evaluates the cone per ray, so it is integrated over the emitter here (over the cone's
         footprint on the emitter when that is small). Inside a true sphere: no cone, and E = πL(3 + cosθ)/4
         (only BSDF rays heading to the centre hit a spot's sphere; see `_sphere_light`). A spot with a
         zero Z scale (`spot_axisless`) lights only where `cycles_radius_share` says.
  SUN    angle 0: E = S·cosθ.  angle α > 0: a cone of directions of half angle β = α/2 with
         L = S / (π sin²β), i.e. E = S when facing the sun (closed form of the clipped cone,
         `cap_form_factor`, exact up to α = 180°).
`light.power` already holds energy · 2^exposure (exposure verified) and `light.color` any
temperature tint. Optional attributes, read with getattr (absent → Blender's default):
  light.use_soft_falloff (POINT/SPOT, default True): True → the emitter is a disk of radius r at the
      light centre facing x (Cycles' "soft falloff"; facing receiver E = I/(d² + r²), smooth through
      d = 0); False → a true sphere (E = I/d² for d > r, E = π·L = I/r² inside it, no spot cone
      inside). They differ by the factor d²/(d²+r²): −6 % at d = 4r, −1 % at d = 10r.
  light.normalize (default True): False → the power is not divided by the emitter area:
      AREA and POINT/SPOT with r > 0: L = P / π;  SUN with α > 0: L = S;  delta lights unaffected.
AREA `spread` < 180° (Cycles narrows the emission lobe) is not modelled: full 180° assumed.
Smooth shading: with `geometric` normals, the light's directions above the shading normal's horizon but below
the geometric surface count at Cycles' MIS weight only (its diffuse BSDF never samples there): band_loss for
suns and point/spot lights, polygon_band_loss for area lights, with each light's own sampling pdf; suns are
picked among the scene's suns as its light tree does (sun_pick), other lights as if alone.
"""
from __future__ import annotations

import numpy as np

from .snapshot import AREA, DISK, ELLIPSE, POINT, SPOT, SUN, Light

_EPS = 1e-12
ROUND_SIDES = 64
SMALL_LIGHT = 1e-2      # below this extent / distance a light is integrated as a point (polygon_form_factor)
CHUNK = 8192


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, _EPS)


def _edge_term(a: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """acos(â·b̂) · n·normalize(a×b) for (N,3) arrays; 0 for degenerate edges."""
    an, bn = _normalize(a), _normalize(b)
    cos = np.clip(np.sum(an * bn, axis=-1), -1.0, 1.0)
    theta = np.arccos(cos)
    c = np.cross(a, b)
    cl = np.linalg.norm(c, axis=-1)
    proj = np.sum(c * n, axis=-1) / np.maximum(cl, _EPS)
    return np.where(cl > _EPS * _EPS, theta * proj, 0.0)


def subtends_small(verts: np.ndarray) -> np.ndarray:
    """(N,) whether each polygon (N, K, 3, relative to its receiver) subtends less than SMALL_LIGHT (its
    extent from its centroid over the centroid's distance): polygon_form_factor takes it as a point, and
    the smooth-normal band (polygon_band_loss) leaves it out, as irradiance.glsl does."""
    centre = verts.mean(axis=1)
    rel = verts - centre[:, None, :]
    extent2 = np.max(np.einsum("nkc,nkc->nk", rel, rel), axis=1)
    return extent2 < SMALL_LIGHT * SMALL_LIGHT * np.einsum("nc,nc->n", centre, centre)


def polygon_form_factor(verts: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Σ-term of Lambert's formula, divided by 2, i.e. E/L for a polygon clipped to n·v > 0.

    verts: (N, K, 3) polygon vertices relative to each receiver point, convex (wound CCW about the
    direction from the point towards the polygon gives a positive sum; the result takes |Σ|);
    normals: (N, 3) unit. Returns (N,) ≥ 0.
    """
    n = normals
    K = verts.shape[1]
    # A polygon subtending less than SMALL_LIGHT (extent / distance) is integrated as a point: its vector
    # area A times cosθ_x·cosθ_light / d², within SMALL_LIGHT² of the exact value. The edge sum cannot be
    # used there: its O(1) terms cancel down to the O(size²) result, so their rounding is amplified by
    # (distance / size)² (a 1e-4 rad sun came out 20 % off in float64).
    small = subtends_small(verts)
    if small.any():
        centre = verts.mean(axis=1)
        rel = verts - centre[:, None, :]
        c2 = np.einsum("nc,nc->n", centre, centre)
        out = np.empty(verts.shape[0])
        r, c, cc = rel[small], centre[small], c2[small]
        vec_area = 0.5 * np.cross(r, np.roll(r, -1, axis=1)).sum(axis=1)
        w = c / np.sqrt(cc)[:, None]
        out[small] = (np.maximum(np.einsum("nc,nc->n", n[small], w), 0.0)
                      * np.abs(np.einsum("nc,nc->n", vec_area, w)) / cc)
        if (~small).any():
            out[~small] = polygon_form_factor(verts[~small], normals[~small])
        return out
    d = np.einsum("nkc,nc->nk", verts, n)  # signed heights above the tangent plane
    total = np.zeros(verts.shape[0])
    exit_pt = np.zeros_like(n)
    entry_pt = np.zeros_like(n)
    has_exit = np.zeros(verts.shape[0], bool)
    has_entry = np.zeros(verts.shape[0], bool)
    for i in range(K):
        j = (i + 1) % K
        a, b = verts[:, i], verts[:, j]
        da, db = d[:, i], d[:, j]
        ina, inb = da > 0.0, db > 0.0
        # point where the edge crosses the tangent plane (only used when exactly one end is inside)
        denom = da - db
        t = np.where(np.abs(denom) > _EPS, da / np.where(np.abs(denom) > _EPS, denom, 1.0), 0.0)
        cross_pt = a + t[:, None] * (b - a)
        leaving = ina & ~inb
        entering = ~ina & inb
        s = np.where(entering[:, None], cross_pt, a)  # clipped segment start
        e = np.where(leaving[:, None], cross_pt, b)  # clipped segment end
        total += np.where(ina | inb, _edge_term(s, e, n), 0.0)
        exit_pt = np.where(leaving[:, None], cross_pt, exit_pt)
        entry_pt = np.where(entering[:, None], cross_pt, entry_pt)
        has_exit |= leaving
        has_entry |= entering
    # the clipped polygon is closed along the horizon, from the exit point back to the entry point
    closing = has_exit & has_entry
    total += np.where(closing, _edge_term(exit_pt, entry_pt, n), 0.0)
    # the clipped polygon is one convex region, so |Σ| is right for either winding
    return 0.5 * np.abs(total)


def cap_form_factor(cos_t: np.ndarray, s2: float) -> np.ndarray:
    """E/L of a cone of directions of half angle β (s2 = sin²β) whose axis makes cos_t with the receiver
    normal, clipped to the receiver's hemisphere. Snyder's closed form (MSR-TR-96-11, 1996; Lagarde & de
    Rousiers, "Moving Frostbite to PBR", 2014, §4.7.2 eq. 44); exact for every β up to 90° (a 180° sun)."""
    c = np.clip(np.asarray(cos_t, np.float64), -1.0, 1.0)
    whole = c * c >= s2                                   # the cone is wholly above or wholly below
    out = np.pi * s2 * np.maximum(c, 0.0)
    if not whole.all():
        cp = c[~whole]
        st = np.sqrt(1.0 - cp * cp)
        x = np.sqrt(max(1.0 / s2 - 1.0, 0.0))             # cot β
        y = np.clip(-x * cp / st, -1.0, 1.0)
        sty = st * np.sqrt(1.0 - y * y)
        out[~whole] = np.maximum((cp * np.arccos(y) - x * sty) * s2 + np.arctan2(sty, x), 0.0)
    return out


def _round_polygon(rx, ry, sides: int = ROUND_SIDES) -> np.ndarray:
    """(sides, 2) CCW regular polygon inscribed-scaled so its area equals π·rx·ry."""
    k = np.sqrt(2.0 * np.pi / (sides * np.sin(2.0 * np.pi / sides)))
    phi = 2.0 * np.pi * (np.arange(sides) + 0.5) / sides
    return np.stack([k * rx * np.cos(phi), k * ry * np.sin(phi)], axis=-1)


def _rect_polygon(hx, hy) -> np.ndarray:
    return np.array([[hx, -hy], [hx, hy], [-hx, hy], [-hx, -hy]], dtype=np.float64)


def _disk_facing(centre: np.ndarray, radius: np.ndarray, axis: np.ndarray,
                 sides: int = ROUND_SIDES) -> np.ndarray:
    """(N, sides, 3) disk polygons (absolute positions) centred at `centre` (N,3), radius (N,), with
    normal `axis` (N,3, unit, pointing away from the receiver), wound CCW about `axis`."""
    t, b = _disk_frame(axis)
    poly = _round_polygon(1.0, 1.0, sides)  # (sides, 2)
    return (centre[:, None, :]
            + radius[:, None, None] * (poly[None, :, 0:1] * t[:, None, :] + poly[None, :, 1:2] * b[:, None, :]))


def spot_attenuation(light: Light, directions: np.ndarray) -> np.ndarray:
    """Cycles' spot cone factor for unit `directions` (N,3) from the light towards the receiver.

    Cycles (kernel/light/spot.h): the direction goes through the inverse object transform and is
    renormalised (Light.spot_to_local), which for perpendicular axes is the light's local frame divided by
    the object scale per axis: w = normalize(d·X/sx, d·Y/sy, d·(-Z)/sz);
    att = smoothstep((w.z − cos(spot_size/2)) / ((1 − cos(spot_size/2))·spot_blend)), with
    smoothstep(t) = 3t² − 2t³ on [0,1] (clamped). No cosine factor. blend 0 → hard edge.
    """
    local = directions @ light.spot_to_local().T        # the inverse object map (Light.spot_to_local)
    wz = -_normalize(local)[:, 2]
    cos_half = np.cos(0.5 * light.spot_size)
    width = (1.0 - cos_half) * light.spot_blend
    if width > 0.0:
        t = np.clip((wz - cos_half) / width, 0.0, 1.0)
        return t * t * (3.0 - 2.0 * t)
    return (wz > cos_half).astype(np.float64)


def _disk_frame(axis: np.ndarray):
    helper = np.where(np.abs(axis[:, 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    t = _normalize(np.cross(helper, axis))
    return t, np.cross(axis, t)


def _disk_cell_centres(centre, radius, axis, x, rings: int, sectors: int) -> np.ndarray:
    """(N, rings·sectors, 3) centres of cells of the disk (facing x) that subtend equal solid angles from x:
    the share inside radius r is (1 − D/√(D² + r²)) / (1 − D/√(D² + ρ²)) at distance D."""
    t, b = _disk_frame(axis)
    D = np.linalg.norm(centre - x, axis=-1)
    whole = 1.0 - D / np.sqrt(D * D + radius * radius)
    k = 1.0 - whole[:, None] * ((np.arange(rings) + 0.5) / rings)[None, :]      # D/√(D² + r²) per ring
    rad = D[:, None] * np.sqrt(np.maximum(1.0 / (k * k) - 1.0, 0.0))               # (N, rings)
    phi = 2.0 * np.pi * (np.arange(sectors) + 0.5) / sectors
    u = (rad[:, :, None] * np.cos(phi)[None, None, :]).reshape(len(D), -1)
    v = (rad[:, :, None] * np.sin(phi)[None, None, :]).reshape(len(D), -1)
    return centre[:, None, :] + u[..., None] * t[:, None, :] + v[..., None] * b[:, None, :]


def _spot_disk_mean(light: Light, centre, radius, axis, x, n, rings: int, sectors: int) -> tuple:
    """The spot's attenuation averaged over the disk's equal-solid-angle cells, weighted by the receiver's
    cosine, (N,); and whether the cells or as many points on the disk's rim disagree, (N,) bool."""
    cells = _disk_cell_centres(centre, radius, axis, x, rings, sectors)     # (N, C, 3)
    t, b = _disk_frame(axis)
    phi = 2.0 * np.pi * (np.arange(sectors) + 0.5) / sectors
    rim = centre[:, None, :] + radius[:, None, None] * (np.cos(phi)[None, :, None] * t[:, None, :]
                                                        + np.sin(phi)[None, :, None] * b[:, None, :])
    q = np.concatenate([cells, rim], axis=1) - x[:, None, :]
    q2 = np.maximum(np.sum(q * q, axis=-1), _EPS)
    qn = q / np.sqrt(q2)[..., None]
    att = spot_attenuation(light, -qn.reshape(-1, 3)).reshape(q2.shape)
    c = cells.shape[1]
    w = np.maximum(np.einsum("ncj,nj->nc", qn[:, :c], n), 0.0)      # the cells hold equal solid angles
    mean = np.sum(w * att[:, :c], axis=1) / np.maximum(np.sum(w, axis=1), _EPS)
    return mean, att.min(axis=1) < att.max(axis=1)


def spot_tan_wide(light: Light) -> float:
    """tan of the spot cone's widest half angle in world space: the object scale stretches the cone by
    scale_x/scale_z and scale_y/scale_z (as Cycles' "larger spread"); a sheared spot's from its edge."""
    if light.spot_linear is not None:
        return spot_edge_tans(light)[2]
    s = np.maximum(np.abs(np.asarray(light.spot_scale, np.float64)), _EPS)
    return float(np.tan(0.5 * light.spot_size) * max(s[0], s[1]) / s[2])


# Directions around a sheared spot's cone edge that spot_edge_tans takes its maxima over, and the margin that
# keeps them above the true maxima (the sampled maximum of a smooth curve falls short by O(step²) ≈ 1e-5).
SPOT_EDGE_STEPS, SPOT_EDGE_MARGIN = 720, 1.001


def spot_edge_tans(light: Light) -> tuple[float, float, float]:
    """For a spot with sheared axes (Light.spot_linear): the largest |tan| of its cone's outer edge along the
    frame's X and Y, and off its -Z, in `matrix`'s frame (inf where the edge reaches the frame's X/Y plane).
    The edge is the image under the object map of Cycles' round cone cos = cos(spot_size/2); as the image of
    a convex cone around local -Z it is convex around the frame's -Z (the image of that axis), so these
    bound it."""
    half = min(0.5 * light.spot_size, 0.5 * np.pi)
    phi = np.linspace(0.0, 2.0 * np.pi, SPOT_EDGE_STEPS, endpoint=False)
    edge = np.stack([np.sin(half) * np.cos(phi), np.sin(half) * np.sin(phi), np.full_like(phi, -np.cos(half))])
    v = np.asarray(light.spot_linear, np.float64) @ edge
    depth = -v[2]
    if np.any(depth <= 1e-9 * np.linalg.norm(v, axis=0)):
        return np.inf, np.inf, np.inf
    t = v[:2] / depth
    return tuple(float(SPOT_EDGE_MARGIN * x) for x in (np.abs(t[0]).max(), np.abs(t[1]).max(),
                                                       np.hypot(t[0], t[1]).max()))


# Spot lights with a radius: the cone attenuation is evaluated per ray in Cycles, so it is integrated over
# the emitter: through a SPOT_GRID × SPOT_GRID grid of the cone's footprint on the disk's plane where that
# footprint's box (clipped to the disk) is smaller than r², otherwise as a mean over SPOT_RINGS × SPOT_SECTORS
# cells of equal solid angle (SPOT_FINE where the cone's edge crosses the disk) times the disk's exact form
# factor.
SPOT_RINGS, SPOT_SECTORS = 4, 16
SPOT_FINE = (12, 24)        # where the cone's edge crosses the disk (_spot_disk_mean's `split`)
SPOT_GRID = 24


def _spot_footprint(light: Light, centre, rr, x, n) -> np.ndarray:
    """E/L (N,) integrated over the box, clipped to the disk (centre, radius rr, facing x), that bounds the cut
    of the disk's plane by the cone of the rays reaching x inside the spot's widest half angle; NaN where the
    box is too large for it to pay (glsl/shading/irradiance.glsl spot_footprint is the same construction)."""
    c = centre - x
    H = np.maximum(np.linalg.norm(c, axis=-1), _EPS)
    normal = c / H[:, None]
    back = light.matrix[:3, 2] / max(np.linalg.norm(light.matrix[:3, 2]), _EPS)   # -(emission direction)
    cos_g = normal @ back
    beta = float(np.arctan(spot_tan_wide(light)))
    gamma = np.arccos(np.clip(cos_g, -1.0, 1.0))
    bounded = gamma + beta < 1.55
    g_far = np.minimum(gamma + beta, 1.55)
    t0 = np.maximum(H * np.tan(np.maximum(gamma - beta, -1.55)), -rr)
    t1 = np.where(bounded, np.minimum(H * np.tan(g_far), rr), rr)
    half_s = np.where(bounded, np.minimum(H * np.sin(beta) / np.sqrt(np.maximum(
        np.cos(g_far) * np.cos(gamma - beta), _EPS)), rr), rr)
    away = (gamma - beta >= 1.5707) | (t1 <= t0)
    out = np.where(away, 0.0, np.nan)
    ok = ~away & ((t1 - t0) * 2.0 * half_s < rr * rr)
    if not ok.any():
        return out
    c, normal, cos_g, t0, t1, half_s, n_, rr_ = (v[ok] for v in (c, normal, cos_g, t0, t1, half_s, n, rr))
    tilt = back[None, :] - normal * cos_g[:, None]
    tl = np.linalg.norm(tilt, axis=-1)
    helper, _ = _disk_frame(normal)
    tilt = np.where(tl[:, None] > 1e-6, tilt / np.maximum(tl, _EPS)[:, None], helper)
    side = np.cross(normal, tilt)
    g = (np.arange(SPOT_GRID) + 0.5) / SPOT_GRID
    gt = t0[:, None] + (t1 - t0)[:, None] * g[None, :]                  # (M, G)
    gs = half_s[:, None] * (2.0 * g[None, :] - 1.0)
    tt = np.repeat(gt, SPOT_GRID, axis=1)                               # (M, G·G)
    ss = np.tile(gs, (1, SPOT_GRID))
    p = c[:, None, :] + tt[..., None] * tilt[:, None, :] + ss[..., None] * side[:, None, :]
    inside = tt * tt + ss * ss <= (rr_ * rr_)[:, None]
    d2 = np.maximum(np.sum(p * p, axis=-1), _EPS)
    w = p / np.sqrt(d2)[..., None]
    att = spot_attenuation(light, -w.reshape(-1, 3)).reshape(d2.shape)
    f = np.maximum(np.einsum("mcj,mj->mc", w, n_), 0.0) * np.einsum("mcj,mj->mc", w, normal) / d2 * att
    cell = (t1 - t0) * 2.0 * half_s / SPOT_GRID ** 2
    out[ok] = np.sum(np.where(inside, f, 0.0), axis=1) * cell
    return out


# Relative steps of the distances cycles_radius_share averages over (64 of them, 32 float32 ulps apart): far
# below the spread of Cycles' own shading points in a pixel, wide enough to sample the rounding's low bits.
RESOLVE_STEPS, RESOLVE_STEP = 64, 2.0 ** -18


def cycles_radius_share(d: np.ndarray, radius: float, soft_falloff: bool) -> np.ndarray:
    """Share of Cycles' samples, (N,) in [0, 1], in which its light tree still sees a spot without an
    emission axis (zero Z scale) at distances `d` from its centre. With the axis at zero the importance of
    the spot is proportional to the sine of the half angle θu its radius subtends (kernel/light/tree.h
    light_tree_importance, spot.h spot_light_tree_parameters), and θu comes from cos θu = d/√(r² + d²) (soft
    falloff) or √(1 − r²/d²) (sphere) in float32: from about 2800·r to 5800·r that rounds to 1 for more
    and more of the points, the importance to 0, and the light is not sampled (its BSDF hits on so small an
    emitter are too rare to count: measured, 1024 spp stay dark). Which points round depends on the low bits
    of d, so the same float32 operations are averaged over RESOLVE_STEPS distances around d."""
    r = np.float32(radius)
    steps = (np.arange(RESOLVE_STEPS) - 0.5 * (RESOLVE_STEPS - 1)) * RESOLVE_STEP
    d32 = (np.asarray(d, np.float64)[:, None] * (1.0 + steps)[None, :]).astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        if soft_falloff:
            cos_u = d32 / np.sqrt(r * r + d32 * d32)
        else:
            s = r / d32
            cos_u = np.where(d32 > r, np.sqrt(np.float32(1.0) - s * s), np.float32(-1.0))
    return np.mean(cos_u < np.float32(1.0), axis=1)


def _sphere_light(light: Light, x: np.ndarray, n: np.ndarray, g: np.ndarray) -> np.ndarray:
    """E per unit colour for a POINT or SPOT light (spot attenuation included), (N,) array; `g` the geometric
    normals, for the smooth-normal band (band_loss), the light picked alone."""
    P = float(light.power)
    c = light.position
    to_l = c[None, :] - x
    d2 = np.sum(to_l * to_l, axis=-1)
    d = np.sqrt(d2)
    axis = to_l / np.maximum(d, _EPS)[:, None]
    is_spot = light.kind == SPOT
    r = float(light.radius)
    if r <= 0.0:
        # delta light: intensity I = P/(4π) W/sr, E = I·cosθ / d²   (measured against Cycles)
        cos = np.maximum(np.sum(axis * n, axis=-1), 0.0)
        e = np.where(d2 > _EPS, P / (4.0 * np.pi) * cos / np.maximum(d2, _EPS), 0.0)
        return e * spot_attenuation(light, -axis) if is_spot else e
    # sphere of radius r: L = P / (π · 4πr²) (normalize=True) or L = P / π (normalize=False),
    # measured against Cycles. So I = P/(4π) far away, as for r = 0.
    if getattr(light, "normalize", True):
        radiance = P / (np.pi * 4.0 * np.pi * r * r)
    else:
        radiance = P / np.pi
    inside = d <= r
    if getattr(light, "use_soft_falloff", True):
        # soft falloff (Blender's default): the light is a disk of radius r at the centre, facing x
        centre = np.broadcast_to(c, x.shape)
        rr = np.full(x.shape[0], r)
        inside = np.zeros_like(inside)
    else:
        # true sphere == the disk of its tangency circle: radius r·sqrt(d²−r²)/d at distance (d²−r²)/d
        dd = np.maximum(d, r * (1.0 + 1e-9))
        centre = x + axis * ((dd * dd - r * r) / dd)[:, None]
        rr = r * np.sqrt(dd * dd - r * r) / dd
    # The band, as irradiance.glsl takes it: the soft-falloff disk sampled by area, the true sphere's cone
    # uniformly (Cycles' point_light_sample)
    D2 = np.sum((centre - x) ** 2, axis=-1)
    cos_beta = np.sqrt(D2 / np.maximum(D2 + rr * rr, 1e-300))
    if getattr(light, "use_soft_falloff", True):
        loss = band_loss(n, g, axis, cos_beta, D2 / (np.pi * np.maximum(rr * rr, 1e-300)), 3.0)
    else:
        loss = band_loss(n, g, axis, cos_beta, 1.0 / (2.0 * np.pi * np.maximum(1.0 - cos_beta, 1e-300)))
    if not is_spot:
        ff = np.maximum(polygon_form_factor(_disk_facing(centre, rr, axis) - x[:, None, :], n) - loss, 0.0)
    else:
        # Cycles evaluates the cone per ray (direction from the emitter sample towards x, no cosine),
        # so average the attenuation over equal-area cells of the disk, weighted by each cell's
        # point-approximated form factor cos_x·cos_disk/dist², times the exact disk form factor.
        mean_att, split = _spot_disk_mean(light, centre, rr, axis, x, n, SPOT_RINGS, SPOT_SECTORS)
        if split.any():     # the cone's edge crosses the disk: finer cells (irradiance.glsl spot_over_disk)
            mean_att[split] = _spot_disk_mean(light, centre[split], rr[split], axis[split], x[split], n[split],
                                              *SPOT_FINE)[0]
        ff = np.maximum(polygon_form_factor(_disk_facing(centre, rr, axis) - x[:, None, :], n) - loss, 0.0) * mean_att
        foot = _spot_footprint(light, centre, rr, x, n)
        ff = np.where(np.isnan(foot), ff, foot)
    e = radiance * ff
    # inside a true sphere the whole hemisphere has radiance L, and Cycles skips the spot cone; a spot's
    # sphere is one-sided for BSDF rays (only those heading to its centre hit it), so with MIS Cycles keeps
    # (3 + cosθ)/4 of it, θ between the normal and the direction to the centre
    # (without a cone, Cycles samples the inside over the cosine hemisphere, the BSDF's pdf: the band keeps
    # half, irradiance.glsl)
    inside_e = radiance * np.pi
    if is_spot:
        inside_e = inside_e * (0.75 + 0.25 * np.sum(axis * n, axis=-1))
    else:
        inside_e = inside_e * (1.0 - 0.25 * (1.0 - np.clip(np.sum(n * g, axis=-1), -1.0, 1.0)))
    e = np.where(inside, inside_e, e)
    if is_spot and getattr(light, "spot_axisless", False):
        e = e * cycles_radius_share(d, r, getattr(light, "use_soft_falloff", True))
    return e


BAND_PSI, BAND_THETA = 6, 8     # glsl/shading/irradiance.glsl's band quadrature
SUN_MAX_HALF = 0.5 * np.pi - 1e-4     # widest half angle a sun's disk of directions is drawn with
MAX_SUNS = 8                          # glsl/shading/irradiance.glsl's MAX_SUNS


def tree_suns(lights) -> list:
    """The suns among `lights`, in scene order, sharp ones too: Cycles' light tree holds them all in its
    distant leaf, and every one of them takes a share of the picks (sun_pick)."""
    return [lt for lt in lights if lt.kind == SUN]


def sun_tree_terms(sun: Light) -> tuple:
    """What Cycles' light tree weighs a sun by (sun_pick): the unit direction towards it, its strength (the
    channel mean) and the cosine of its half angle."""
    toward = np.asarray(sun.matrix, np.float64)[:3, 2]
    toward = toward / max(float(np.linalg.norm(toward)), 1e-30)
    strength = float(np.mean(np.asarray(sun.color, np.float64)) * sun.power)
    return toward, strength, float(np.cos(min(sun.angle / 2.0, SUN_MAX_HALF)))


def _band_wedge(ns, ng):
    """The wedges between the two horizons (irradiance.glsl band_wedge): live (N,) where the normals differ,
    and for those the common line a, b0 in the geometric plane and the angle δ."""
    a = np.cross(ng, ns)
    s = np.linalg.norm(a, axis=-1)
    live = s >= 1e-4
    a = a[live] / s[live, None]
    delta = np.arctan2(s[live], np.einsum("nc,nc->n", ns[live], ng[live]))
    return live, a, np.cross(a, ng[live]), delta


def _band_arc(a, b, t0, t1, ok, psi, delta, axis, p0, power: float) -> np.ndarray:
    """∫ (1 − w)·cosθ_s over the arcs θ ∈ [t0, t1] at ψ (0 where not `ok`), the light's pdf
    p0 / |ω·axis|^power (irradiance.glsl band_arc)."""
    k = np.sin(delta - psi) / np.pi
    d_theta = np.where(ok, t1 - t0, 0.0) / BAND_THETA
    total = np.zeros(len(a))
    for i in range(BAND_THETA):
        t = t0 + (i + 0.5) * d_theta
        st = np.sin(t)
        pb2 = (k * st) ** 2
        if power > 0.0:
            c = np.abs(np.einsum("nc,nc->n", np.cos(t)[:, None] * a + st[:, None] * b,
                                 np.broadcast_to(axis, a.shape)))
            pl = p0 / np.maximum(c, 1e-4) ** power
        else:
            pl = p0
        total += st * st * pb2 / np.maximum(pl * pl + pb2, 1e-300)
    return np.where(ok, total * d_theta * np.sin(delta - psi), 0.0)


def band_loss(ns: np.ndarray, ng: np.ndarray, axis, cos_beta, light_pdf, pdf_power: float = 0.0) -> np.ndarray:
    """∫ (1 − w)·cosθ_s dω over the directions of the cone (axis, cos β; one or one per receiver) above the
    shading normals' horizon and below the geometric normals' (N,3 each, unit), w = p_l²/(p_l² + p_b²) the
    light strategy's power-heuristic weight in Cycles' MIS (p_b = cosθ_s/π; its diffuse BSDF never samples
    below the geometric surface), p_l = `light_pdf` / cos^pdf_power of the angle off the axis, per steradian.
    The same quadrature as irradiance.glsl's band_loss, which explains its parametrisation."""
    ns, ng = np.asarray(ns, np.float64), np.asarray(ng, np.float64)
    count = len(ns)
    axis = np.broadcast_to(np.asarray(axis, np.float64), (count, 3))
    cos_beta = np.broadcast_to(np.asarray(cos_beta, np.float64), (count,))
    light_pdf = np.broadcast_to(np.asarray(light_pdf, np.float64), (count,))
    sin_beta = np.sqrt(np.maximum(1.0 - cos_beta * cos_beta, 0.0))
    out = np.zeros(count)
    wedge, a, b0, delta = _band_wedge(ns, ng)
    straddles = (np.einsum("nc,nc->n", ng, axis) < sin_beta) & (np.einsum("nc,nc->n", ns, axis) > -sin_beta)
    live, keep = wedge & straddles, straddles[wedge]
    if not live.any():
        return out
    a, b0, delta = a[keep], b0[keep], delta[keep]
    ng_, ax, cb, pdf = ng[live], axis[live], cos_beta[live], light_pdf[live]
    a_axis = np.einsum("nc,nc->n", a, ax)
    d_psi = delta / BAND_PSI
    loss = np.zeros(len(a))
    for j in range(BAND_PSI):
        psi = (j + 0.5) * d_psi
        b = np.cos(psi)[:, None] * b0 - np.sin(psi)[:, None] * ng_
        b_axis = np.einsum("nc,nc->n", b, ax)
        R = np.hypot(a_axis, b_axis)
        theta0 = np.arctan2(b_axis, a_axis)
        half = np.arccos(np.clip(cb / np.maximum(R, 1e-30), -1.0, 1.0))
        t0, t1 = np.maximum(theta0 - half, 0.0), np.minimum(theta0 + half, np.pi)
        loss += _band_arc(a, b, t0, t1, (R > cb) & (t1 > t0), psi, delta, ax, pdf, pdf_power)
    out[live] = loss * d_psi
    return out


def _triangle_solid_angle(a, b, c):
    """Solid angles (N,) of the triangles (a, b, c) (N,3 each) seen from the origin (Van Oosterom & Strackee
    1983)."""
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    num = np.abs(np.einsum("nc,nc->n", a, np.cross(b, c)))
    den = (la * lb * lc + np.einsum("nc,nc->n", a, b) * lc + np.einsum("nc,nc->n", a, c) * lb
           + np.einsum("nc,nc->n", b, c) * la)
    return 2.0 * np.arctan2(num, den)


def polygon_band_loss(ns, ng, C, U, V, emit, ellipse: bool) -> np.ndarray:
    """band_loss for an area light C + u·U + v·V (C (N,3) relative to each receiver; |u|, |v| ≤ 1, or
    u² + v² ≤ 1 for an ellipse), picked alone: Cycles samples a rectangle uniformly over its solid angle and
    an ellipse by area. irradiance.glsl's polygon_band_loss, which explains the clipping."""
    ns, ng, C = (np.asarray(v, np.float64) for v in (ns, ng, C))
    U, V, emit = (np.asarray(v, np.float64).reshape(3) for v in (U, V, emit))
    out = np.zeros(len(ns))
    live, a, b0, delta = _band_wedge(ns, ng)
    if not live.any():
        return out
    ng_, C = ng[live], C[live]
    if ellipse:
        p0 = (C @ emit) ** 2 / (np.pi * np.sqrt((U @ U) * (V @ V)))     # p_l = h²/(A·|ω·emit|³)
    else:
        p00, p10, p11, p01 = C - U - V, C + U - V, C + U + V, C - U + V
        p0 = 1.0 / np.maximum(_triangle_solid_angle(p00, p10, p11) + _triangle_solid_angle(p00, p11, p01), 1e-300)
    d_psi = delta / BAND_PSI
    loss = np.zeros(len(C))
    for j in range(BAND_PSI):
        psi = (j + 0.5) * d_psi
        b = np.cos(psi)[:, None] * b0 - np.sin(psi)[:, None] * ng_
        m = np.cross(a, b)
        al, be, ga = m @ U, m @ V, np.einsum("nc,nc->n", m, C)
        nn = al * al + be * be
        ok = nn >= 1e-20
        nn_ = np.where(ok, nn, 1.0)
        f = -ga[:, None] * np.stack([al, be], -1) / nn_[:, None]
        direction = np.stack([-be, al], -1) / np.sqrt(nn_)[:, None]
        if ellipse:
            d2 = np.sum(f * f, axis=-1)
            ok &= d2 < 1.0
            s1 = np.sqrt(np.maximum(1.0 - d2, 0.0))
            s0 = -s1
        else:
            s0, s1 = np.full(len(C), -1e9), np.full(len(C), 1e9)
            for k in range(2):
                dk, fk = direction[:, k], f[:, k]
                flat = np.abs(dk) < 1e-12
                dk_ = np.where(flat, 1.0, dk)
                e0, e1 = (-1.0 - fk) / dk_, (1.0 - fk) / dk_
                s0 = np.where(flat, s0, np.maximum(s0, np.minimum(e0, e1)))
                s1 = np.where(flat, np.where(np.abs(fk) > 1.0, -1e9, s1), np.minimum(s1, np.maximum(e0, e1)))
            ok &= s1 > s0
        ends = [C + (f[:, 0] + e * direction[:, 0])[:, None] * U + (f[:, 1] + e * direction[:, 1])[:, None] * V
                for e in (s0, s1)]
        th0, th1 = (np.arctan2(np.einsum("nc,nc->n", q, b), np.einsum("nc,nc->n", q, a)) for q in ends)
        lo, hi = np.minimum(th0, th1), np.maximum(th0, th1)
        wrap = hi - lo > np.pi                        # the arc passes through -a
        lo, hi = np.where(wrap, hi, lo), np.where(wrap, np.pi, hi)
        t0, t1 = np.maximum(lo, 0.0), np.minimum(hi, np.pi)
        loss += _band_arc(a, b, t0, t1, ok & (t1 > t0), psi, delta, emit, p0, 3.0 if ellipse else 0.0)
    out[live] = loss * d_psi
    return out


def sun_pick(light: Light, lights, normals: np.ndarray) -> np.ndarray:
    """Probability (N,) that Cycles' light tree picks `light` among the scene's suns with an angle at
    receivers with shading `normals` (kernel/light/tree.h: the distant lights share one leaf): ½(max/Σmax +
    min/Σmin) over the importance bounds of each sun's cone, or ½(max/Σmax + 1/count) where every min is 0.
    Irradiance.glsl's sun_pick, which states the bounds; point, spot and area lights are not counted."""
    suns = tree_suns(lights)[:MAX_SUNS]
    n = np.asarray(normals, np.float64)
    hi, lo = np.zeros((len(suns), len(n))), np.zeros((len(suns), len(n)))
    own = -1
    for i, sun in enumerate(suns):
        toward, strength, cu = sun_tree_terms(sun)
        su = np.sqrt(1.0 - cu * cu)
        ci = np.clip(n @ toward, -1.0, 1.0)
        si = np.sqrt(1.0 - ci * ci)
        c_min = np.where(ci >= cu, 1.0, ci * cu + si * su)
        seen = c_min >= 0.0
        hi[i] = np.where(seen, c_min * strength, 0.0)
        lo[i] = np.where(seen, np.maximum(ci * cu - si * su, 0.0) * strength * cu, 0.0)
        own = i if sun is light else own
    if own < 0:
        return np.ones(len(n))
    sum_hi, sum_lo, count = hi.sum(0), lo.sum(0), (hi > 0.0).sum(0)
    by_lo = np.where(sum_lo > 0.0, lo[own] / np.maximum(sum_lo, 1e-300),
                     np.where(hi[own] > 0.0, 1.0 / np.maximum(count, 1), 0.0))
    return np.where(sum_hi > 0.0, 0.5 * (hi[own] / np.maximum(sum_hi, 1e-300) + by_lo), 1.0)


def irradiance(light: Light, points: np.ndarray, normals: np.ndarray, geometric=None, lights=None) -> np.ndarray:
    """Unoccluded irradiance (N,3) float64 RGB at `points` (N,3) with unit shading `normals` (N,3) and
    `geometric` normals (None: the same), `light` one of the scene's `lights` (None: alone). A sun's cone is
    weighed in the band between the two horizons as Cycles' MIS weighs it (band_loss)."""
    x = np.asarray(points, np.float64).reshape(-1, 3)
    n = _normalize(np.asarray(normals, np.float64).reshape(-1, 3))
    g = n if geometric is None else _normalize(np.asarray(geometric, np.float64).reshape(-1, 3))
    if x.shape[0] > CHUNK:  # bound the temporaries (N × polygon vertices × 3)
        return np.concatenate([irradiance(light, x[i:i + CHUNK], n[i:i + CHUNK], g[i:i + CHUNK], lights)
                               for i in range(0, x.shape[0], CHUNK)], axis=0)
    color = np.asarray(light.color, np.float64).reshape(3)
    P = float(light.power)
    m = np.asarray(light.matrix, np.float64)
    N = x.shape[0]
    if N == 0 or P == 0.0:
        return np.zeros((N, 3))

    if light.kind == AREA:
        sx, sy = float(light.size_x), float(light.size_y)
        if sx <= 0.0 or sy <= 0.0:
            return np.zeros((N, 3))
        area = light.area
        # area light: L = P / (π·A), measured against Cycles (normalize=False: L = P/π)
        radiance = P / (np.pi * area) if getattr(light, "normalize", True) else P / np.pi
        if light.shape in (DISK, ELLIPSE):
            local = _round_polygon(0.5 * sx, 0.5 * sy)
        else:
            local = _rect_polygon(0.5 * sx, 0.5 * sy)
        world = m[:3, 3] + local[:, 0:1] * m[:3, 0] + local[:, 1:2] * m[:3, 1]  # (K,3)
        verts = world[None, :, :] - x[:, None, :]
        # emits towards local -Z only: receivers must be strictly on the -Z side
        front = (x - m[:3, 3]) @ m[:3, 2] < 0.0
        # CCW about local +Z == CCW about the direction from a front receiver to the light
        ff = polygon_form_factor(verts, n)
        # the smooth-normal band (polygon_band_loss), past the small-light limit as in irradiance.glsl
        wide = ~subtends_small(verts)
        if wide.any():
            half_u, half_v = m[:3, 0] * 0.5 * sx, m[:3, 1] * 0.5 * sy
            ff[wide] = np.maximum(ff[wide] - polygon_band_loss(
                n[wide], g[wide], m[:3, 3] - x[wide], half_u, half_v, -m[:3, 2], light.shape in (DISK, ELLIPSE)), 0.0)
        e = np.where(front, radiance * ff, 0.0)
    elif light.kind in (POINT, SPOT):
        e = _sphere_light(light, x, n, g)
    elif light.kind == SUN:
        to_sun = m[:3, 2]  # light travels along -Z, so the sun is towards +Z
        beta = 0.5 * float(light.angle)
        if beta <= 0.0:
            e = P * np.maximum(n @ to_sun, 0.0)  # sun: E = S·cosθ
        else:
            # sun with angle: cone of half angle β (a disk of radius tanβ at unit distance) of
            # radiance L = S / (π sin²β), so that E = S at normal incidence; measured against Cycles
            sb = np.sin(min(beta, 0.5 * np.pi))
            radiance = P / (np.pi * sb * sb) if getattr(light, "normalize", True) else P
            cap = cap_form_factor(n @ to_sun, sb * sb)
            cos_beta = float(np.cos(min(beta, SUN_MAX_HALF)))
            pdf = sun_pick(light, [light] if lights is None else lights, n) / (2.0 * np.pi * (1.0 - cos_beta))
            e = radiance * np.maximum(cap - band_loss(n, g, to_sun, cos_beta, pdf), 0.0)
    else:
        raise ValueError(f"unknown light kind {light.kind!r}")
    e = np.where(np.isfinite(e), e, 0.0)
    return e[:, None] * color[None, :]
