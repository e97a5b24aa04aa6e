"""GPU resources of one frame: uploaded geometry, the camera G-buffer, and small helpers that every technique
uses (render a depth map from a light view, run a compute pass over the image). Runs on the GPU thread."""
from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from ..core.lightview import LightView
from ..core.snapshot import SceneSnapshot
from .geometry import SceneGeometry, SoupGeometry
from .programs import bind_samplers, mat_uniform, program, set_uniforms

NO_OCCLUDER = 3.0e38    # depth-map value where nothing was drawn


class Timings(dict):
    """Milliseconds per stage, summed over lights and samples. `stage()` times a block after ctx.finish():
    llvmpipe gives no useful GL timer queries, so wall clock around a finished pipeline it is. Nested stages
    count once: an outer stage is charged only the time its inner stages did not claim."""

    def __init__(self, ctx):
        super().__init__()
        self._ctx = ctx
        self._inner: list[float] = []

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        self._inner.append(0.0)
        try:
            yield
        finally:
            self._ctx.finish()
            elapsed = (time.perf_counter() - start) * 1000.0
            inner = self._inner.pop()
            if self._inner:
                self._inner[-1] += elapsed
            self[name] = self.get(name, 0.0) + elapsed - inner


class Frame:
    """Everything a technique needs on the GPU for one camera image."""

    def __init__(self, worker, snap: SceneSnapshot, settings, geometry: SceneGeometry | None = None):
        self.worker = worker
        self.ctx = ctx = worker.ctx
        self.snap = snap
        self.settings = settings
        self.width, self.height = snap.camera.width, snap.camera.height
        self.timings = Timings(ctx)
        self._owned: list = []
        self.progress = None            # pipeline.Progress, set by the pipeline
        self.bias_uniforms: dict = {}   # u_bias / u_normal_offset, shared by every technique
        self.warnings: list[str] = list(snap.warnings)  # FrameResult.warnings
        self.stats: dict = {}           # counters techniques add (FrameResult.stats)
        with self.timings.stage("upload"):
            self.geometry = geometry or self._own(SoupGeometry(ctx, snap))
        self._depth_targets: dict = {}
        self.gbuffer = self._render_gbuffer()

    def warn(self, text: str) -> None:
        """A warning for the user, once per frame."""
        if text not in self.warnings:
            self.warnings.append(text)

    def count(self, **counters) -> None:
        """Add to the frame's statistics counters."""
        for name, value in counters.items():
            self.stats[name] = self.stats.get(name, 0) + value

    def _own(self, obj):
        self._owned.append(obj)
        return obj

    def texture(self, size, components, dtype="f4"):
        tex = self._own(self.ctx.texture(size, components, dtype=dtype))
        tex.filter = (0x2600, 0x2600)   # GL_NEAREST: techniques fetch texels themselves
        return tex

    def release(self):
        for obj in reversed(self._owned):
            obj.release()
        self._owned.clear()

    # ---- camera G-buffer -------------------------------------------------------------------------------
    def _render_gbuffer(self):
        ctx, cam = self.ctx, self.snap.camera
        size = (self.width, self.height)
        g = {name: self.texture(size, 4) for name in ("g_position", "g_normal", "g_geometric", "g_albedo")}
        depth = self._own(ctx.depth_texture(size))
        fbo = self._own(ctx.framebuffer(color_attachments=list(g.values()), depth_attachment=depth))
        with self.timings.stage("gbuffer"):
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable(ctx.DEPTH_TEST)
            ctx.disable(ctx.CULL_FACE)
            prog = program(self.worker, "common/gbuffer.vert", "common/gbuffer.frag")
            inv_view = np.linalg.inv(cam.view)
            set_uniforms(prog, {
                "u_view": mat_uniform(cam.view), "u_view_proj": mat_uniform(cam.projection @ cam.view),
                "u_camera_position": tuple(inv_view[:3, 3]), "u_camera_ortho": int(cam.is_ortho),
                "u_camera_forward": tuple(-inv_view[:3, 2]),
            })
            self.geometry.render(ctx, prog, "receiver")
        return g

    def read(self, tex, components: int | None = None) -> np.ndarray:
        """Texture → (H, W, C) float32, row 0 at the bottom (GL and Blender agree on that)."""
        c = components or tex.components
        return np.frombuffer(tex.read(), dtype=np.float32).reshape(tex.height, tex.width, tex.components)[..., :c]

    # ---- shadow maps -----------------------------------------------------------------------------------
    def render_depth_map(self, view: LightView, target=None):
        """Linear light depth of the casters seen from `view`, as an R32F texture (NO_OCCLUDER where empty).
        Render targets are reused between calls of the same size (REFERENCE renders hundreds)."""
        ctx = self.ctx
        size = (view.width, view.height)
        if target is None:
            cached = self._depth_targets.get(size)
            if cached is None:
                tex = self.texture(size, 1)
                depth = self._own(ctx.depth_texture(size))
                fbo = self._own(ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
                cached = self._depth_targets[size] = (tex, fbo)
            tex, fbo = cached
        else:
            tex, fbo = target
        fbo.use()
        fbo.clear(NO_OCCLUDER, 0.0, 0.0, 0.0, depth=1.0)
        if self.geometry.has_casters:
            ctx.enable(ctx.DEPTH_TEST)
            ctx.disable(ctx.CULL_FACE)
            prog = program(self.worker, "common/depth.vert", "common/depth.frag")
            set_uniforms(prog, {"u_light_view": mat_uniform(view.view), "u_light_view_proj": mat_uniform(view.view_proj)})
            self.geometry.render(ctx, prog, "caster", position_only=True)
        return tex

    def new_depth_target(self, view: LightView):
        """A private depth-map target, for structures that must outlive the next render_depth_map call."""
        size = (view.width, view.height)
        tex = self.texture(size, 1)
        depth = self._own(self.ctx.depth_texture(size))
        return tex, self._own(self.ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))

    # ---- compute passes --------------------------------------------------------------------------------
    def dispatch(self, compute: str, uniforms: dict | None = None, samplers: dict | None = None,
                 images: dict | None = None, defines: dict | None = None, size=None) -> None:
        """Run glsl/`compute` once per image pixel. `samplers`: uniform name → texture; `images`: binding →
        texture (bound read-write). The G-buffer is always bound under its own names."""
        prog = program(self.worker, compute=compute, defines=defines)
        w, h = size or (self.width, self.height)
        bind_samplers(prog, {**self.gbuffer, **(samplers or {})})
        for binding, tex in (images or {}).items():
            tex.bind_to_image(binding, read=True, write=True)
        set_uniforms(prog, {"u_image_size": (w, h), **(uniforms or {})})
        prog.run((w + 7) // 8, (h + 7) // 8, 1)
        self.ctx.memory_barrier()


