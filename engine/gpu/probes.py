"""Small GPU probes used by tests: the shader's irradiance and penumbra spread at arbitrary points."""
from __future__ import annotations

import numpy as np

from ..core.shading import light_defines, light_uniforms
from ..core.snapshot import Light
from .programs import program, set_uniforms


def _run_points(worker, shader: str, uniforms: dict, inputs: list[bytes], out_bytes: int, n: int,
                defines: dict | None = None, out_binding: int = 1) -> bytes:
    """Run compute `shader` over n items: `inputs` bound as storage buffers in order, with the output buffer
    (out_bytes per item) at `out_binding` among them; returns the output's bytes. On the GPU thread."""
    ctx = worker.ctx
    bufs = [ctx.buffer(data) for data in inputs]
    out = ctx.buffer(reserve=out_bytes * max(n, 1))
    bufs.insert(out_binding, out)
    try:
        prog = program(worker, compute=shader, defines=defines)
        set_uniforms(prog, {**uniforms, "u_count": n})
        for binding, buf in enumerate(bufs):
            buf.bind_to_storage_buffer(binding)
        prog.run((n + 63) // 64)
        ctx.finish()
        return out.read()
    finally:
        for buf in bufs:
            buf.release()


def irradiance_at(worker, light: Light, points: np.ndarray, normals: np.ndarray, geometric=None,
                  lights=None) -> np.ndarray:
    """The shader's unoccluded irradiance at arbitrary points (N, 3) → (N, 3), with shading `normals` and
    `geometric` normals (None: the same), `light` one of the scene's `lights` (None: alone); runs on the GPU
    thread. Used to check glsl/shading/irradiance.glsl against engine/core/irradiance.py."""
    n = len(points)
    pad = lambda a: np.c_[np.asarray(a, np.float32), np.zeros(n, np.float32)].tobytes()
    data = _run_points(worker, "shading/irradiance_points.comp", light_uniforms(light, lights),
                       [pad(points), pad(normals), pad(normals if geometric is None else geometric)], 16, n,
                       defines=light_defines(light), out_binding=2)
    return np.frombuffer(data, np.float32).reshape(-1, 4)[:n, :3].astype(np.float64)


def penumbra_spread_at(worker, z: np.ndarray, d: np.ndarray, ortho: bool) -> np.ndarray:
    """glsl/common/penumbra.glsl's penumbra_spread and penumbra_spread_clamped at (z, d) pairs → (N, 2);
    runs on the GPU thread. Used to check the GLSL relation against engine/core/light_shape.py."""
    n = len(z)
    pairs = np.c_[np.asarray(z, np.float32), np.asarray(d, np.float32)].tobytes()
    data = _run_points(worker, "common/penumbra_points.comp", {"u_ortho": int(ortho)}, [pairs], 8, n)
    return np.frombuffer(data, np.float32).reshape(-1, 2)[:n].astype(np.float64)


def light_footprint_at(worker, local: np.ndarray, half, *, sphere: bool, ortho: bool = False,
                       spot_cone=(0.0, 0.0)) -> dict:
    """glsl/common/light_view.glsl's light_footprint for receivers at light-local points (N, 3) under a light of
    half extent `half` (x, y), clipped by a spot's cone of half-angle tangents `spot_cone` (x, y; 0: none) →
    {"centre": (N, 2), "half_box": (N, 2), "axes": (N, 2, 2) (rows: plane x, y)}; runs on the GPU thread. Used to
    check the footprint against a ray projection of the light."""
    n = len(local)
    points = np.c_[np.asarray(local, np.float32), np.zeros(n, np.float32)].tobytes()
    data = _run_points(worker, "common/footprint_points.comp",
                       {"u_light_half": tuple(float(h) for h in half), "u_light_sphere": int(sphere),
                        "u_light_ortho": int(ortho), "u_spot_cone": tuple(float(t) for t in spot_cone)},
                       [points], 32, n)
    out = np.frombuffer(data, np.float32).reshape(-1, 2, 4)[:n].astype(np.float64)
    # GLSL matrices are column-major: axes[0] is the column for kernel x.
    return {"centre": out[:, 0, :2], "half_box": out[:, 0, 2:],
            "axes": np.stack([out[:, 1, [0, 2]], out[:, 1, [1, 3]]], axis=1)}
