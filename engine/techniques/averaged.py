"""Averaged shadow maps (user-facing identifier REFERENCE): the average of N hard shadow maps rendered from
stratified points of the light — the "1024 shadow maps" ground truth the soft-shadow-map papers compare
against (e.g. Atty et al. §4.1). Penumbra's own ground truth is Cycles (engine/measure/reference.py).

Sample points: an R2 low-discrepancy set over the square, mapped to the disk by Shirley & Chiu's concentric
map for round lights. Sphere lights are sampled over their great disk facing the receivers (the view's XY
plane); suns uniformly over their cone of directions, each weighted by the receiver's cosine. Each map's view keeps the light's axes and is refitted from the
sample point.
"""
from __future__ import annotations

import numpy as np

from ..core import lightview
from ..core.shader_constants import WEIGHT_AREA, WEIGHT_NONE, WEIGHT_SPHERE, WEIGHT_SUN
from ..core.snapshot import AREA, DISK, ELLIPSE, SUN, Light
from ..gpu.frame import MAX_DEPTH_LAYERS
from .base import MAP_SIZE_SWEEP, Option, Technique


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
        # Uniform over the cone's solid angle, as Cycles samples a sun (the disk's area maps to 1 − cosθ),
        # returned as tan θ along the sample's azimuth: uniform in tan θ would crowd the rim of a wide sun.
        r = np.linalg.norm(q, axis=1)
        cos_t = np.maximum(1.0 - r * r * (1.0 - np.cos(min(light.angle / 2.0, np.pi / 2))), 1e-4)
        tan_t = np.sqrt(1.0 - cos_t * cos_t) / cos_t
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.nan_to_num(q / r[:, None]) * tan_t[:, None]
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
    # The identifier stays REFERENCE (stored in .blend files and scripts); its settings say what it does.
    options = (
        Option("averaged_light_samples", 64, "Light Samples", "Hard shadow maps averaged per light",
               min=1, max=4096),
        Option("averaged_weighted", True, "Weighted",
               "Weight each light sample by its unoccluded contribution at the pixel"),
    )
    reads_shared = ("seed",)
    coarse = {"averaged_light_samples": 8}
    sweep = MAP_SIZE_SWEEP + tuple({"averaged_light_samples": n} for n in (16, 64, 256, 1024))

    def visibility(self, frame, lc, out):
        s, light = frame.settings, lc.light
        n = 1 if light.is_delta else int(s.option("averaged_light_samples"))
        offsets = light_samples(light, n, s.seed) if not light.is_delta else np.zeros((1, 2))
        sums = frame.texture((frame.width, frame.height), 4)        # zero-filled
        weight_mode = WEIGHT_NONE
        if s.option("averaged_weighted"):
            weight_mode = WEIGHT_AREA if light.kind == AREA else WEIGHT_SUN if light.kind == SUN else WEIGHT_SPHERE
        samples = []                        # (view, sample position, emission axis) per light sample
        for i, offset in enumerate(offsets):
            if i % 64 == 0:
                frame.progress.check()      # thousands of views take a while to fit: stay cancellable
            emit = light.direction
            if light.kind == SUN:
                tilted = tilted_sun(light, offset)
                view = lightview.fit(tilted, lc.receivers, lc.casters, s.shadow_map_size)
                sample_world, emit = light.position, tilted.direction
            else:
                local = np.array([offset[0], offset[1], 0.0])
                # A cube face keeps its turn: every sample's map looks the way the face looks.
                view = lightview.fit(light, lc.receivers, lc.casters, s.shadow_map_size, origin_local=local,
                                     frame=lc.view.frame, face=lc.view.face)
                sample_world = (np.linalg.inv(view.view) @ np.array([0.0, 0.0, 0.0, 1.0]))[:3]
            samples.append((view, sample_world, emit))
        # Batches of maps rendered in one layered pass and accumulated in one dispatch (in sample order).
        largest = max(v.width * v.height for v, _, _ in samples)
        batch = int(min(MAX_DEPTH_LAYERS, max(1, BATCH_BYTES // (4 * largest))))
        done = 0
        for first in range(0, len(samples), batch):
            frame.progress.check()
            part = samples[first:first + batch]
            with frame.timings.stage("shadow_map"):
                maps = frame.render_depth_layers([v for v, _, _ in part])
            with frame.timings.stage("visibility"):
                records = frame.buffer(_sample_records(part))
                frame.dispatch("averaged/accumulate.comp", {
                    **frame.bias_uniforms, "u_count": len(part), "u_weight_mode": weight_mode},
                    samplers={"g_irradiance": lc.irradiance, "u_depth_maps": maps}, images={0: sums},
                    buffers={1: records})
            frame.give_back(maps)           # the next batch draws into the same array
            frame.give_back(records)
            done += len(part)
            frame.progress.step(done / len(samples), f"{light.name}: sample {done}/{len(samples)}")
        frame.dispatch("averaged/resolve.comp", samplers={"u_sums": sums}, images={0: out})


BATCH_BYTES = 64 << 20          # at most this much texture array per batch


def _sample_records(part) -> bytes:
    """averaged/accumulate.comp's Sample structs (std430, 144 bytes each)."""
    rec = np.zeros((len(part), 36), np.float32)
    for k, (view, position, emit) in enumerate(part):
        u = view.uniforms()
        rec[k, 0:16] = u["u_light_view"]
        rec[k, 16:20] = u["u_light_window"]
        rec[k, 20:24] = (*u["u_light_depth_range"], u["u_texel_tan"], u["u_light_ortho"])
        rec[k, 24:26] = np.array(u["u_map_size"], np.int32).view(np.float32)
        rec[k, 28:31], rec[k, 32:35] = position, emit
    return rec.tobytes()
