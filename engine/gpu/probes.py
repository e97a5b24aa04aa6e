"""Small GPU probes used by tests: the shader's irradiance and penumbra spread at arbitrary points."""
from __future__ import annotations

import numpy as np

from ..core.shading import light_defines, light_uniforms
from ..core.snapshot import Light
from .programs import program, set_uniforms


def irradiance_at(worker, light: Light, points: np.ndarray, normals: np.ndarray, geometric=None,
                  lights=None) -> np.ndarray:
    """The shader's unoccluded irradiance at arbitrary points (N, 3) → (N, 3), with shading `normals` and
    `geometric` normals (None: the same), `light` one of the scene's `lights` (None: alone); runs on the GPU
    thread. Used to check glsl/shading/irradiance.glsl against engine/core/irradiance.py."""
    ctx = worker.ctx
    n = len(points)
    pad = lambda a: np.c_[np.asarray(a, np.float32), np.zeros(n, np.float32)].tobytes()
    bufs = [ctx.buffer(pad(points)), ctx.buffer(pad(normals)), ctx.buffer(reserve=16 * max(n, 1)),
            ctx.buffer(pad(normals if geometric is None else geometric))]
    try:
        prog = program(worker, compute="shading/irradiance_points.comp", defines=light_defines(light))
        set_uniforms(prog, {**light_uniforms(light, lights), "u_count": n})
        for binding, buf in enumerate(bufs):
            buf.bind_to_storage_buffer(binding)
        prog.run((n + 63) // 64)
        ctx.finish()
        return np.frombuffer(bufs[2].read(), np.float32).reshape(-1, 4)[:n, :3].astype(np.float64)
    finally:
        for buf in bufs:
            buf.release()


def penumbra_spread_at(worker, z: np.ndarray, d: np.ndarray, ortho: bool) -> np.ndarray:
    """glsl/common/penumbra.glsl's penumbra_spread and penumbra_spread_clamped at (z, d) pairs → (N, 2);
    runs on the GPU thread. Used to check the GLSL relation against engine/core/light_shape.py."""
    ctx = worker.ctx
    n = len(z)
    pairs = np.c_[np.asarray(z, np.float32), np.asarray(d, np.float32)].tobytes()
    bufs = [ctx.buffer(pairs), ctx.buffer(reserve=8 * max(n, 1))]
    try:
        prog = program(worker, compute="common/penumbra_points.comp")
        set_uniforms(prog, {"u_count": n, "u_ortho": int(ortho)})
        for binding, buf in enumerate(bufs):
            buf.bind_to_storage_buffer(binding)
        prog.run((n + 63) // 64)
        ctx.finish()
        return np.frombuffer(bufs[1].read(), np.float32).reshape(-1, 2)[:n].astype(np.float64)
    finally:
        for buf in bufs:
            buf.release()
