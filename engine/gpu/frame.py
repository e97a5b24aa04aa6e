"""GPU resources of one frame: uploaded geometry, the camera G-buffer, and small helpers that every technique
uses (render a depth map from a light view, run a compute pass over the image). Runs on the GPU thread."""
from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np

from ..core.lightview import LightView
from ..core.shader_constants import NO_OCCLUDER
from ..core.snapshot import SceneSnapshot
from .geometry import SceneGeometry, SoupGeometry
from .pool import pool_of
from .multisample import (GBUFFER_NAMES, MSAA_BYTES_PER_PIXEL, MSAA_SAMPLES, EdgeList, multisampled_targets,
                          resolve_first_sample)
from .programs import bind_samplers, mat_uniform, program, set_uniforms
from .state import gl_state

MAX_DEPTH_LAYERS = 32       # render_depth_layers: geometry-shader invocations, one per layer (GL guarantees 32)
_DTYPE_BYTES = {"f1": 1, "u1": 1, "i1": 1, "f2": 2, "u2": 2, "i2": 2, "f4": 4, "u4": 4, "i4": 4}


def resource_bytes(obj) -> int:
    """GPU memory held by `obj`: its `nbytes` if it states one, a texture's (or texture array's) texels,
    or the sum over a list, tuple or dict of such; 0 for anything else (None, numbers)."""
    if obj is None:
        return 0
    if hasattr(obj, "glo"):             # a moderngl object
        if hasattr(obj, "components") and hasattr(obj, "dtype"):
            layers = getattr(obj, "layers", None) or getattr(obj, "depth", None) or 1
            return int(obj.width * obj.height * layers * obj.components * _DTYPE_BYTES.get(obj.dtype, 4))
        size = getattr(obj, "size", 0)  # a buffer's bytes; a framebuffer's size is a tuple: nothing held
        return size if isinstance(size, int) else 0
    own = getattr(obj, "nbytes", None)  # structures that count themselves; numpy arrays
    if isinstance(own, int):
        return own
    if isinstance(obj, dict):
        return sum(resource_bytes(v) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(resource_bytes(v) for v in obj)
    return 0

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


def check_image_size(ctx, width: int, height: int, extra_gpu_bytes_per_pixel: int = 0) -> None:
    """Refuse (ValueError) a frame the context cannot hold, before anything is allocated;
    `extra_gpu_bytes_per_pixel`: GPU memory beyond GPU_BYTES_PER_PIXEL (the multisampled G-buffer)."""
    max_size = int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384))
    viewport = ctx.info.get("GL_MAX_VIEWPORT_DIMS")
    if viewport:
        max_size = min(max_size, *[int(v) for v in viewport])
    software = "llvmpipe" in str(ctx.info.get("GL_RENDERER", "")).lower()
    per_pixel = HOST_BYTES_PER_PIXEL + (GPU_BYTES_PER_PIXEL + extra_gpu_bytes_per_pixel if software else 0)
    problem = image_size_problem(width, height, max_size, available_host_bytes(), per_pixel)
    if problem:
        raise ValueError(problem)


class Timings(dict):
    """Milliseconds per stage, summed over lights and samples. With `sync` (per-stage timing asked for: the
    bench), `stage()` times a block after ctx.finish(): llvmpipe gives no useful GL timer queries, so wall
    clock around a finished pipeline it is. Without it (a normal render, the viewport) nothing waits for the
    GPU here, and a stage's time is what the CPU spent issuing it: GPU work lands in whichever later stage
    reads a result back. Nested stages count once: an outer stage is charged only the time its inner stages
    did not claim."""

    def __init__(self, ctx, sync: bool = True):
        super().__init__()
        self._ctx = ctx
        self.sync = sync
        self._inner: list[float] = []

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        self._inner.append(0.0)
        try:
            yield
        finally:
            if self.sync:
                self._ctx.finish()
            elapsed = (time.perf_counter() - start) * 1000.0
            inner = self._inner.pop()
            if self._inner:
                self._inner[-1] += elapsed
            self[name] = self.get(name, 0.0) + elapsed - inner


class Frame:
    """Everything a technique needs on the GPU for one camera image."""

    def __init__(self, worker, snap: SceneSnapshot, settings, geometry: SceneGeometry | None = None,
                 stage_times: bool = False):
        self.worker = worker
        self.ctx = ctx = worker.ctx
        self.snap = snap
        self.settings = settings
        self.width, self.height = snap.camera.width, snap.camera.height
        check_image_size(ctx, self.width, self.height,
                         MSAA_BYTES_PER_PIXEL if getattr(settings, "antialiasing", False) else 0)
        self.timings = Timings(ctx, sync=stage_times)     # GPU waits only when per-stage times are asked
        self._owned: list = []
        self.pool = pool_of(worker)
        self._from_pool: list = []      # pooled objects this frame took: given back by release()
        self._per_light: list = []
        self.progress = None            # pipeline.Progress, set by the pipeline
        self.view_owner: tuple | None = None   # (owner texture, index) inside view_of
        self.bias_uniforms: dict = {}   # u_bias / u_normal_offset / u_terminator_offset, shared by every technique
        self.warnings: list[str] = list(snap.warnings)  # FrameResult.warnings
        self.stats: dict = {}           # counters techniques add (FrameResult.stats)
        with self.timings.stage("upload"):
            self.geometry = geometry or self.own(SoupGeometry(ctx, snap))
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

    def own(self, obj):
        """Release `obj` with the frame."""
        self._owned.append(obj)
        return obj

    def own_per_light(self, obj):
        """Release `obj` when the pipeline finishes the current light (`end_light`): large per-light
        structures (an MSSM) must not pile up over the lights of one frame."""
        self._per_light.append(obj)
        return obj

    def end_light(self) -> None:
        for obj in reversed(self._per_light):
            if self.pool.pooled(obj):
                self.pool.give_back(obj)
            else:
                obj.release()
        self._per_light.clear()

    def texture_array(self, size, components, dtype="f4"):
        """A (width, height, layers) texture array from the pool (contents undefined until written)."""
        return self._pooled(self.pool.texture_array(size, components, dtype))

    def give_back(self, obj) -> None:
        """Return a pooled object before the frame ends, for the next taker (REFERENCE's batches); GL runs
        commands in order, so work already issued with it still sees its old contents."""
        self._from_pool.remove(obj)
        self.pool.give_back(obj)

    def texture_array_per_light(self, size, components, dtype="f4"):
        """A (width, height, layers) texture array from the pool, given back when the current light ends
        (contents undefined until written)."""
        return self.own_per_light(self.pool.texture_array(size, components, dtype))

    def buffer(self, data: bytes):
        """A storage buffer holding `data`, from the worker's pool (gpu/pool.py), back to it with the frame."""
        return self._pooled(self.pool.buffer(data))

    def texture(self, size, components, dtype="f4"):
        """A zero-filled texture, GL_NEAREST, from the worker's pool, back to it with the frame."""
        return self._pooled(self.pool.texture(size, components, dtype))

    def depth_texture(self, size, samples: int = 0):
        """A depth texture (contents undefined until cleared) from the pool, back to it with the frame."""
        return self._pooled(self.pool.depth_texture(size, samples))

    def multisample_texture(self, size, components, samples, dtype="f4"):
        """A multisampled texture (contents undefined until cleared) from the pool, back to it with the frame."""
        return self._pooled(self.pool.multisample_texture(size, components, samples, dtype))

    def reserved_buffer(self, nbytes: int):
        """A storage buffer of `nbytes` (contents undefined) from the pool, back to it with the frame."""
        return self._pooled(self.pool.reserved_buffer(nbytes))

    def framebuffer(self, color_attachments, depth_attachment=None):
        """A framebuffer of these attachments: the pool's cached one when they all come from the pool."""
        attachments = [*color_attachments, *([depth_attachment] if depth_attachment is not None else [])]
        if all(self.pool.pooled(a) for a in attachments):
            return self.pool.framebuffer(color_attachments, depth_attachment)
        return self.own(self.ctx.framebuffer(color_attachments=list(color_attachments),
                                             depth_attachment=depth_attachment))

    def _pooled(self, obj):
        self._from_pool.append(obj)
        return obj

    def release(self):
        self.end_light()
        for obj in reversed(self._owned):
            obj.release()
        self._owned.clear()
        for obj in reversed(self._from_pool):    # last in, first out: the next frame gets them in this order
            self.pool.give_back(obj)
        self._from_pool.clear()
        self.pool.end_frame()

    # ---- camera G-buffer -------------------------------------------------------------------------------
    def _render_gbuffer(self):
        size = (self.width, self.height)
        g = {name: self.texture(size, 4) for name in GBUFFER_NAMES}
        # Anti-aliasing (Schwarz & Stamminger 2008, §7) adds a multisampled G-buffer that only the shading
        # reads; the per-pixel one every technique reads is either drawn as without it (pixel centres) or
        # the multisamples' first (the paper's choice: see engine/gpu/multisample.py).
        self.gbuffer_samples = self.msaa_edges = None
        aa = getattr(self.settings, "antialiasing", False)
        first = aa and self.settings.aa_visibility_sample == "FIRST"
        if aa:
            self.gbuffer_samples = multisampled_targets(self, size, full=first)
            # the terminator lift matters only where visibility is computed (shading never reads it)
            self._draw_gbuffer(self.gbuffer_samples, MSAA_SAMPLES, "gbuffer_msaa", lift=first)
        self.gbuffer = g                # dispatch binds it
        if first:
            with self.timings.stage("gbuffer_resolve"):
                resolve_first_sample(self, self.gbuffer_samples, g)
        else:
            self._draw_gbuffer(g, 0)
        if aa:
            with self.timings.stage("gbuffer_resolve"):
                self.msaa_edges = EdgeList(self, self.gbuffer_samples)     # its buffer is the pool's
            self.count(msaa_edge_pixels=self.msaa_edges.count)
        return g

    def _draw_gbuffer(self, targets: dict, samples: int, stage: str = "gbuffer", lift: bool = True) -> None:
        """Draw the receivers from the camera into the G-buffer `targets` (with a depth buffer of `samples`),
        timed as `stage`. `lift`: compute the shadow-terminator lift of smooth triangles (g_geometric.w)."""
        ctx, cam = self.ctx, self.snap.camera
        depth = self.depth_texture((self.width, self.height), samples)
        fbo = self.framebuffer(list(targets.values()), depth)
        with self.timings.stage(stage):
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable(ctx.DEPTH_TEST)
            ctx.disable(ctx.CULL_FACE)
            if lift and self.geometry.has_smooth:   # the lift needs each fragment's whole triangle
                prog = program(self.worker, "common/gbuffer.vert", "common/gbuffer.frag",
                               geometry="common/gbuffer.geom", defines={"TERMINATOR_LIFT": 1})
            else:
                prog = program(self.worker, "common/gbuffer.vert", "common/gbuffer.frag")
            inv_view = np.linalg.inv(cam.view)
            set_uniforms(prog, {
                "u_view": mat_uniform(cam.view), "u_view_proj": mat_uniform(cam.projection @ cam.view),
                "u_camera_position": tuple(inv_view[:3, 3]), "u_camera_ortho": int(cam.is_ortho),
                "u_camera_forward": tuple(-inv_view[:3, 2]),
            })
            self.geometry.render(ctx, prog, "receiver")

    def read(self, tex, components: int | None = None) -> np.ndarray:
        """Texture → (H, W, C) float32, row 0 at the bottom (GL and Blender agree on that)."""
        c = components or tex.components
        return np.frombuffer(tex.read(), dtype=np.float32).reshape(tex.height, tex.width, tex.components)[..., :c]

    # ---- light-view rasterisation ------------------------------------------------------------------------
    def target(self, size, components: int = 1, dtype: str = "f4"):
        """A (colour texture, framebuffer with a depth buffer) pair owned by the frame."""
        tex = self.texture(size, components, dtype)
        depth = self.depth_texture(size)
        return tex, self.framebuffer([tex], depth)

    def rasterise(self, target, prog, view, view_proj, *, role: str = "caster", draws=((None, {}),),
                  clear=(NO_OCCLUDER, 0.0, 0.0, 0.0), farthest: bool = False, uniforms: dict | None = None,
                  samplers: dict | None = None):
        """The one routine that draws scene triangles from a light's (or the camera's) eye into `target`:
        positions only, depth-tested, both faces, no blending. `prog` pairs common/depth.vert with a
        fragment shader (depth map, depth peeling, SSM's tagged maps); `draws` is a list of (object indices
        or None for all, uniforms for that draw); `farthest` keeps the farthest fragment instead of the
        nearest (depth cleared to 0, test ">"). Returns the colour texture."""
        ctx = self.ctx
        tex, fbo = target
        fbo.use()
        fbo.clear(*clear, depth=0.0 if farthest else 1.0)
        set_uniforms(prog, {"u_light_view": mat_uniform(view), "u_light_view_proj": mat_uniform(view_proj),
                            **(uniforms or {})})
        if samplers:
            bind_samplers(prog, samplers)
        inside = self._objects_in_frustum(view_proj)    # objects wholly outside the view are not drawn
        with gl_state(ctx, depth_test=True, cull=False, blend=False, depth_func=">" if farthest else "<"):
            for objects, extra in draws:
                if inside is not None:
                    objects = inside if objects is None else objects & inside
                    if not objects:
                        continue
                set_uniforms(prog, extra)
                self.geometry.render(ctx, prog, role, objects, position_only=True)
        return tex

    def _objects_in_frustum(self, view_proj):
        """Indices of the objects whose world box meets the clip volume of `view_proj`, or None when every
        object does (draw everything, as one draw). A box with all 8 corners beyond one clip plane holds no
        triangle that could reach a texel, so leaving it out changes no texel."""
        bounds = np.asarray(self.geometry.object_bounds(), float)
        if bounds.size == 0:
            return None
        lo, hi = bounds[:, 0], bounds[:, 1]
        empty = ~np.all(np.isfinite(lo) & np.isfinite(hi), axis=1)      # objects with no triangles
        lo, hi = np.where(empty[:, None], 0.0, lo), np.where(empty[:, None], 0.0, hi)
        pick = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)], bool)      # the 8 corners
        corners = np.where(pick[None], hi[:, None, :], lo[:, None, :])                   # (N, 8, 3)
        clip = np.concatenate([corners, np.ones(corners.shape[:2] + (1,))], axis=2) @ np.asarray(view_proj).T
        w = clip[..., 3]
        outside = np.zeros(len(bounds), bool)
        for axis in range(3):
            outside |= np.all(clip[..., axis] > w, axis=1) | np.all(clip[..., axis] < -w, axis=1)
        outside &= ~empty
        if not outside.any():
            return None
        return frozenset(int(i) for i in np.flatnonzero(~outside & ~empty))

    def render_depth_map(self, view: LightView, target=None, back_faces: bool = False):
        """Linear light depth of the casters seen from `view`, as an R32F texture (NO_OCCLUDER where empty);
        `back_faces`: of their faces turned away from the view's eye only, into a target of its own.
        Render targets are reused between calls of the same size (REFERENCE renders hundreds)."""
        size = (view.width, view.height)
        if back_faces and target is None:
            target = self.target(size, 1)
        if target is None:
            target = self._depth_targets.get(size)
            if target is None:
                target = self._depth_targets[size] = self.target(size, 1)
        if not self.geometry.has_casters:
            target[1].use()
            target[1].clear(NO_OCCLUDER, 0.0, 0.0, 0.0, depth=1.0)
            return target[0]
        prog = program(self.worker, "common/depth.vert", "common/depth.frag",
                       defines={"BACK_FACES": 1} if back_faces else None)
        return self.rasterise(target, prog, view.view, view.view_proj)

    def render_facet_map(self, view: LightView):
        """The normal of the surface each texel of render_depth_map(view) holds, in the view's frame
        (common/facet.frag), as an RGBA16F texture of its own; (0, 0, 0) where empty."""
        target = self.target((view.width, view.height), 4, "f2")
        if not self.geometry.has_casters:
            target[1].use()
            target[1].clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            return target[0]
        return self.rasterise(target, program(self.worker, "common/depth.vert", "common/facet.frag"), view.view,
                              view.view_proj, clear=(0.0, 0.0, 0.0, 0.0))

    def render_depth_layers(self, views, clip_sphere=None, behind=None):
        """Depth maps of the casters from each of `views` (at most MAX_DEPTH_LAYERS) as the layers of one
        R32F texture array (the largest view's size; a smaller map fills its layer's lower-left corner), in
        one draw: common/depth_layers.geom sends each triangle to every layer, and MIN blending keeps the
        nearest linear depth (NO_OCCLUDER where empty), texel for texel what render_depth_map gives.
        `clip_sphere` (centre, radius): casters inside that sphere are left out. `behind`: an array this call
        made for the same views, whose depths each texel must lie behind (depth peeling: the next nearest
        caster surface, NO_OCCLUDER where there is none)."""
        maps = self._layered_target(views, 1, "f4", NO_OCCLUDER)
        if self.geometry.has_casters:
            self._draw_layers(maps, views, "common/depth.frag", clip_sphere, {"PEEL": 1} if behind is not None else {},
                              {"u_in_front": behind} if behind is not None else {}, minimum=True)
        return maps

    def render_facet_layers(self, views, depths, clip_sphere=None):
        """For the layered depth maps `depths` that render_depth_layers(views, clip_sphere) made, the plane normal
        of the triangle each texel holds, in its view's frame and not oriented (common/facet_layers.frag), as
        an RGBA16F array; (0, 0, 0) where the texel is empty. What render_facet_map gives for one view."""
        facets = self._layered_target(views, 4, "f2", 0.0)
        if self.geometry.has_casters:
            self._draw_layers(facets, views, "common/facet_layers.frag", clip_sphere, {"FACET": 1},
                              {"u_depths": depths})
        return facets

    def _layered_target(self, views, components: int, dtype: str, clear: float):
        """A texture array with a layer per view (the largest view's size), cleared to `clear` and bound as
        the draw target."""
        w, h = max(v.width for v in views), max(v.height for v in views)
        array = self.texture_array((w, h, len(views)), components, dtype)
        fbo = self.framebuffer([array])
        fbo.use()
        fbo.clear(clear, clear if components > 1 else 0.0, clear if components > 2 else 0.0, 0.0)
        return array

    def _draw_layers(self, target, views, fragment: str, clip_sphere, defines: dict, samplers: dict,
                     minimum=False):
        """Draw the casters once into every layer of `target` (the bound array _layered_target made for
        `views`; common/depth_layers.geom), as each view sees them, with `fragment`; MIN blending where
        `minimum`."""
        w, h = target.size[:2]
        rec = np.zeros((len(views), 36), np.float32)    # depth_layers.geom's LayerView structs (std430)
        for k, v in enumerate(views):
            rec[k, 0:16] = np.asarray(v.view, np.float32).T.ravel()
            rec[k, 16:32] = np.asarray(v.view_proj, np.float32).T.ravel()
            rec[k, 32:34] = (v.width / w, v.height / h)
        defines = {"MAX_LAYERS": MAX_DEPTH_LAYERS, **defines}
        uniforms = {"u_count": len(views)}
        if clip_sphere is not None:
            defines["CLIP_SPHERE"] = 1
            uniforms["u_clip_sphere"] = (*map(float, clip_sphere[0]), float(clip_sphere[1]) ** 2)
        prog = program(self.worker, "common/depth_layers.vert", fragment, geometry="common/depth_layers.geom",
                       defines=defines)
        layer_views = self.buffer(rec.tobytes())
        layer_views.bind_to_storage_buffer(0)
        set_uniforms(prog, uniforms)
        bind_samplers(prog, samplers)
        with gl_state(self.ctx, depth_test=False, cull=False, minimum=minimum):
            self.geometry.render(self.ctx, prog, "caster", position_only=True)
        self.give_back(layer_views)

    def new_depth_target(self, view: LightView):
        """A private depth-map target, for structures that must outlive the next render_depth_map call."""
        return self.target((view.width, view.height), 1)

    # ---- compute passes --------------------------------------------------------------------------------
    @contextmanager
    def view_of(self, owner, index: int):
        """While one of a light's several views is made or merged: every dispatch binds the owner texture
        (per pixel, the index of the view that takes it) and `index`, and common/pixel.glsl's pixel_owned
        (so pixel_lit) takes only that view's pixels."""
        self.view_owner = (owner, index)
        try:
            yield
        finally:
            self.view_owner = None

    def dispatch(self, compute: str, uniforms: dict | None = None, samplers: dict | None = None,
                 images: dict | None = None, defines: dict | None = None, size=None, groups=None,
                 buffers: dict | None = None) -> None:
        """Run glsl/`compute` once per image pixel (or as `groups` work groups of 8×8). `samplers`: uniform
        name → texture; `images`: binding → texture (bound read-write); `buffers`: binding → storage buffer.
        The G-buffer is always bound under its own names."""
        prog = program(self.worker, compute=compute, defines=defines)
        w, h = size or (self.width, self.height)
        owner = {} if self.view_owner is None else {"u_view_owner": self.view_owner[0]}
        bind_samplers(prog, {**self.gbuffer, **owner, **(samplers or {})})
        for binding, tex in (images or {}).items():
            tex.bind_to_image(binding, read=True, write=True)
        for binding, buf in (buffers or {}).items():
            buf.bind_to_storage_buffer(binding)
        index = -1.0 if self.view_owner is None else float(self.view_owner[1])
        set_uniforms(prog, {"u_image_size": (w, h), "u_view_index": index, **(uniforms or {})})
        prog.run(*(groups or ((w + 7) // 8, (h + 7) // 8, 1)))
        self.ctx.memory_barrier()


