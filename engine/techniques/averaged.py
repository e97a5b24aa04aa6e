"""REFERENCE: the average of N hard shadow maps rendered from stratified points of the light — the
"1024 shadow maps" ground truth the soft-shadow-map papers compare against (e.g. Atty et al. §4.1).

Sample points: an R2 low-discrepancy set over the square, mapped to the disk by Shirley & Chiu's concentric
map for round lights. Sphere lights are sampled over their great disk facing the receivers (the view's XY
plane); suns over the disk of directions. Each map's view keeps the light's axes and is refitted from the
sample point.
"""
from __future__ import annotations

import numpy as np

from ..core import lightview
from ..core.snapshot import AREA, DISK, ELLIPSE, SUN, Light
from .base import MAP_SIZE_SWEEP, Technique


def unit_square_samples(n: int, seed: int = 0) -> np.ndarray:
    """n points in [-1, 1]², well stratified for any n (R2 sequence with a seeded offset)."""
    g = 1.32471795724474602596
    alpha = np.array([1.0 / g, 1.0 / g ** 2])
    offset = np.random.default_rng(seed).random(2)
    return ((offset + np.arange(1, n + 1)[:, None] * alpha) % 1.0) * 2.0 - 1.0


def concentric_disk(q: np.ndarray) -> np.ndarray:
    """Shirley & Chiu's area-preserving map of [-1, 1]² onto the unit disk."""
    a, b = q[:, 0], q[:, 1]
    use_a = np.abs(a) > np.abs(b)
    r = np.where(use_a, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(use_a, np.pi / 4 * (b / a), np.pi / 2 - np.pi / 4 * (a / b))
    phi = np.nan_to_num(phi)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def light_samples(light: Light, n: int, seed: int = 0) -> np.ndarray:
    """(n, 2) offsets in the light's local XY plane: metres, or tan of the tilt for a sun."""
    q = unit_square_samples(n, seed)
    round_ = light.kind != AREA or light.shape in (DISK, ELLIPSE)
    if round_:
        q = concentric_disk(q)
    if light.kind == AREA:
        return q * np.array([light.size_x / 2.0, light.size_y / 2.0])
    if light.kind == SUN:
        return q * np.tan(light.angle / 2.0)
    return q * light.radius


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


class AveragedMaps(Technique):
    identifier = "REFERENCE"
    label = "Averaged shadow maps"
    description = "Average of N hard shadow maps from points on the light: slow ground truth"
    needs = ()
    coarse = {"reference_samples": 8}
    sweep = MAP_SIZE_SWEEP + tuple({"reference_samples": n} for n in (16, 64, 256, 1024))

    def visibility(self, frame, lc, out):
        s, light = frame.settings, lc.light
        n = 1 if light.is_delta else int(s.reference_samples)
        offsets = light_samples(light, n, s.seed) if not light.is_delta else np.zeros((1, 2))
        sums = frame.texture((frame.width, frame.height), 4)
        sums.write(np.zeros((frame.height, frame.width, 4), np.float32).tobytes())
        weight_mode = 0
        if s.reference_weighted:
            weight_mode = {AREA: 1, SUN: 3}.get(light.kind, 2)
        for i, offset in enumerate(offsets):
            frame.progress.check()
            if light.kind == SUN:
                sample_light = tilted_sun(light, offset)
                view = lightview.fit(sample_light, lc.receivers, lc.casters, s.shadow_map_size)
                sample_world, emit = light.position, sample_light.direction
            else:
                local = np.array([offset[0], offset[1], 0.0])
                view = lightview.fit(light, lc.receivers, lc.casters, s.shadow_map_size, origin_local=local)
                sample_world = (np.linalg.inv(view.view) @ np.array([0.0, 0.0, 0.0, 1.0]))[:3]
                emit = light.direction
            with frame.timings.stage("shadow_map"):
                depth = frame.render_depth_map(view)
            with frame.timings.stage("visibility"):
                frame.dispatch("reference/accumulate.comp", {
                    **frame.bias_uniforms, **view.uniforms(), "u_sample_position": tuple(sample_world),
                    "u_emit_dir": tuple(emit), "u_weight_mode": weight_mode},
                    samplers={"g_irradiance": lc.irradiance, "u_depth_map": depth}, images={0: sums})
            frame.progress.step((i + 1) / len(offsets), f"{light.name}: sample {i + 1}/{len(offsets)}")
        frame.dispatch("reference/resolve.comp", samplers={"u_sums": sums}, images={0: out})
