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

# Memory one frame needs per image pixel, estimated from what it allocates: on the GPU the G-buffer (four
# RGBA32F targets and a depth buffer, 68 B) and the pipeline's sums (four RGBA32F, one RG32F, one R32F, 76 B);
# on the host the readbacks and the finished passes at their peak (~112 B). A software GL (llvmpipe) keeps its
# textures in host memory, so there both count against the RAM available.
GPU_BYTES_PER_PIXEL = 144
HOST_BYTES_PER_PIXEL = 112


def image_size_problem(width: int, height: int, max_size: int, budget_bytes: float | None,
                       bytes_per_pixel: int) -> str | None:
    """Why a width×height frame cannot be allocated (the GL texture limit, or `budget_bytes` of memory at
    `bytes_per_pixel`), with the largest image of the same aspect ratio that would fit; None if it fits."""
    scale, reasons = 1.0, []
    if max(width, height) > max_size:
        scale = min(scale, max_size / max(width, height))
        reasons.append(f"this GPU's largest texture is {max_size}×{max_size} (GL_MAX_TEXTURE_SIZE)")
    need = float(width) * height * bytes_per_pixel
    if budget_bytes is not None and need > budget_bytes:
        scale = min(scale, (budget_bytes / need) ** 0.5)
        reasons.append(f"it needs about {need / 2**30:.1f} GiB and {budget_bytes / 2**30:.1f} GiB is available")
    if not reasons:
        return None
    fit_w, fit_h = max(1, int(width * scale)), max(1, int(height * scale))
    return (f"image {width}×{height} is too large: {'; '.join(reasons)}. At this aspect ratio at most "
            f"{fit_w}×{fit_h} fits (scene resolution or --resolution)")


def available_host_bytes() -> float | None:
    """MemAvailable from /proc/meminfo (Linux, the only platform the extension supports); None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return None


def check_image_size(ctx, width: int, height: int) -> None:
    """Refuse (ValueError) a frame the context cannot hold, before anything is allocated."""
    max_size = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
    viewport = ctx.info.get("GL_MAX_VIEWPORT_DIMS")
    if viewport:
        max_size = min(max_size, *[int(v) for v in viewport])
    software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
    per_pixel = HOST_BYTES_PER_PIXEL + (GPU_BYTES_PER_PIXEL if software else 0)
    problem = image_size_problem(width, height, max_size, available_host_bytes(), per_pixel)
    if problem:
        raise ValueError(problem)


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
        check_image_size(ctx, self.width, self.height)
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


