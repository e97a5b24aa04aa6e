"""Small GPU probes used by tests: the shader's irradiance at arbitrary points."""
from __future__ import annotations

import numpy as np

from ..core.shading import light_defines, light_uniforms
from ..core.snapshot import Light
from .programs import program, set_uniforms


def irradiance_at(worker, light: Light, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """The shader's unoccluded irradiance at arbitrary points (N, 3) → (N, 3); runs on the GPU thread.
    Used to check glsl/shading/irradiance.glsl against engine/core/irradiance.py."""
    ctx = worker.ctx
    n = len(points)
    pad = lambda a: np.c_[np.asarray(a, np.float32), np.zeros(n, np.float32)].tobytes()
    bufs = [ctx.buffer(pad(points)), ctx.buffer(pad(normals)), ctx.buffer(reserve=16 * max(n, 1))]
    try:
        prog = program(worker, compute="shading/irradiance_points.comp", defines=light_defines(light))
        set_uniforms(prog, {**light_uniforms(light), "u_count": n})
        for binding, buf in enumerate(bufs):
            buf.bind_to_storage_buffer(binding)
        prog.run((n + 63) // 64)
        ctx.finish()
        return np.frombuffer(bufs[2].read(), np.float32).reshape(-1, 4)[:n, :3].astype(np.float64)
    finally:
        for buf in bufs:
            buf.release()
