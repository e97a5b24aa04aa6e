"""The interactive viewport, renderer side: GPU-resident geometry and progressive, cancellable frames.

Three parts, split by thread:
  ViewportScene    (Blender's main thread) reads the depsgraph; re-reads a mesh only when the depsgraph says
                   its geometry (or a material) changed; transforms, lights and the camera touch no mesh.
  ViewportGeometry (GPU thread) keeps one object-space vertex buffer per mesh and draws instances with
                   their model matrices, so moving an object uploads nothing.
  ViewportSession  (main thread) submits frames to the GPU thread: a coarse one first, then the full one;
                   a newer request cancels the frames still queued or running. Pixels come back as numpy.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field, replace

import numpy as np

from ..core import lightview
from ..gpu.context import Cancelled, GpuWorker
from ..gpu.geometry import Draw, SceneGeometry, interleave, upload_textures
from ..core.settings import RenderSettings
from ..core.snapshot import Camera, ObjectInfo, SceneSnapshot
from ..core.viewport_state import Instance, MeshPiece, SceneState


# ---------------------------------------------------------------------------------------------------------
# GPU side
# ---------------------------------------------------------------------------------------------------------

class ViewportGeometry(SceneGeometry):
    """Object-space buffers per mesh, instances drawn with model matrices. Lives on the GPU thread."""

    def __init__(self, ctx):
        self._ctx = ctx
        self._buffers: dict[tuple, tuple] = {}     # key → (vbo, vertices, version, local bounds)
        self._textured: dict[tuple, tuple] = {}    # key → (uv buffer, [(map or None, first, count)], GL objects)
        self._instances: list[Instance] = []
        self._objects: list[ObjectInfo] = []
        self._pieces: dict = {}
        self._lights: list = []
        self.uploads: dict[tuple, int] = {}        # key → times uploaded (tests count these)

    def apply(self, state: SceneState) -> None:
        for key in list(self._buffers):
            if key not in state.pieces:
                self._buffers.pop(key)[0].release()
                self._release_textures(key)
        for key, piece in state.pieces.items():
            current = self._buffers.get(key)
            if current is not None and current[2] == piece.version:
                continue
            if current is not None:
                current[0].release()
                self._release_textures(key)
            vbo = self._ctx.buffer(interleave(piece.positions, piece.normals, piece.albedo))
            self._buffers[key] = (vbo, 3 * piece.positions.shape[0], piece.version, piece.bounds)
            if piece.ranges and piece.uv is not None:
                # Each mesh uploads its own images (shared between its slots, not between meshes).
                uv = self._ctx.buffer(np.ascontiguousarray(piece.uv, np.float32).tobytes())
                maps, images, _ = upload_textures(self._ctx, piece.textures)
                ranges = [(maps[i] if i >= 0 else None, 3 * first, 3 * n) for i, first, n in piece.ranges]
                self._textured[key] = (uv, ranges, [*maps, *images, uv])
            self.uploads[key] = self.uploads.get(key, 0) + 1
        self._instances, self._objects = state.instances, state.objects
        self._pieces, self._lights = state.pieces, state.lights
        self.has_casters = any(self._objects[i.object_index].caster for i in self._instances)
        self.forget_facts()             # floors, rooms and convex casters as this state has them

    def draws(self, role, objects=None):
        out = []
        for inst in self._instances:
            info = self._objects[inst.object_index]
            if not (info.caster if role == "caster" else info.receiver):
                continue
            if objects is not None and inst.object_index not in objects:
                continue
            vbo, vertices, _, _ = self._buffers[inst.key]
            m = inst.matrix
            r = m[:3, :3]
            det = float(np.linalg.det(r))
            normal = np.linalg.pinv(r).T
            model, normal = tuple(m.astype(np.float32).T.ravel()), tuple(normal.astype(np.float32).T.ravel())
            textured = self._textured.get(inst.key)
            if textured is None:
                out.append(Draw(vbo, None, vertices, model, normal, det < 0.0))
                continue
            uv, ranges, _ = textured
            out.extend(Draw(vbo, None, count, model, normal, det < 0.0, first=first, texture=tex, uv=uv)
                       for tex, first, count in ranges)
        return out

    def _release_textures(self, key):
        textured = self._textured.pop(key, None)
        for obj in (textured[2] if textured is not None else ()):
            obj.release()

    def culling_snapshot(self) -> SceneSnapshot:
        """The instances' triangles in world space on the CPU, corners ordered as the final render's extraction
        orders them (a mirrored instance's corners 1 and 2 swapped, so that its faces stay counter-clockwise
        from outside): what the final render's culling reads (floors, rooms and convex casters left out of
        the light views that need not hold them), so that the viewport leaves out what it does. Built when a
        frame first asks after a sync, not per redraw."""
        positions, object_id = [], []
        for inst in self._instances:
            piece = self._pieces[inst.key]
            m = np.asarray(inst.matrix, np.float64)
            world = piece.positions.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            if np.linalg.det(m[:3, :3]) < 0.0:
                world = world[:, [0, 2, 1]]
            positions.append(world.astype(np.float32))
            object_id.append(np.full(len(world), inst.object_index, np.int32))
        geometry = SceneSnapshot.empty_geometry()
        if positions:
            p = np.concatenate(positions)
            geometry.update(positions=p, normals=np.zeros_like(p), object_id=np.concatenate(object_id),
                            albedo=np.zeros((len(p), 3), np.float32))
        return SceneSnapshot(objects=self._objects, lights=self._lights, camera=None, name="viewport",
                             **geometry)

    def object_bounds(self):
        out = np.empty((len(self._objects), 2, 3))
        out[:, 0], out[:, 1] = np.inf, -np.inf
        for inst in self._instances:
            lo, hi = self._buffers[inst.key][3]
            world = lightview.to_local(inst.matrix, lightview.box_corners(lo, hi))
            out[inst.object_index, 0] = np.minimum(out[inst.object_index, 0], world.min(axis=0))
            out[inst.object_index, 1] = np.maximum(out[inst.object_index, 1], world.max(axis=0))
        return out

    def release(self):
        for vbo, *_ in self._buffers.values():
            vbo.release()
        for key in list(self._textured):
            self._release_textures(key)
        self._buffers.clear()


# ---------------------------------------------------------------------------------------------------------
# session: progressive, cancellable frames
# ---------------------------------------------------------------------------------------------------------

def coarse_settings(settings: RenderSettings, map_size: int) -> RenderSettings:
    """The quick first frame after a change: a small map, no anti-aliasing (the refined frame has it) and
    the technique's own cheap mode (Technique.coarse)."""
    from ..techniques import get
    changes = {"shadow_map_size": min(map_size, settings.shadow_map_size), "antialiasing": False}
    for name, value in get(settings.technique).coarse.items():
        current = getattr(settings, name) if name in settings.field_names() else settings.option(name)
        numeric = isinstance(value, (int, float)) and not isinstance(value, bool)
        changes[name] = min(value, current) if numeric else value      # numbers are caps, never raised
    return settings.with_(**changes)


@dataclass
class ViewportFrame:
    passes: dict                # pass name → (H, W, C) float32, row 0 at the bottom
    width: int
    height: int
    coarse: bool
    request: int                # the request it answers
    ms: float                   # GPU-thread time of this frame
    timings: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)   # FrameResult.stats: views per light, lights left out, …


class ViewportSession:
    """Owns the viewport's GPU geometry and the frames in flight. Call from Blender's main thread."""

    def __init__(self, worker: GpuWorker | None = None):
        self.worker = worker or GpuWorker.get()
        self.state: SceneState | None = None
        self._geometry: ViewportGeometry | None = None
        self._lock = threading.Lock()
        self._request = 0
        self._last_key = None
        self._jobs: list = []
        self.latest: ViewportFrame | None = None
        self.cancelled = 0          # frames dropped because a newer request came (tests read it)
        self.error: str | None = None

    # -- scene ---------------------------------------------------------------------------------------------
    def apply_state(self, state: SceneState) -> None:
        """Hand a new scene state to the GPU thread without waiting: frames of the old scene are cancelled,
        and the GPU thread applies the upload before any newer frame (its queue is first in, first out). An
        upload error is kept in `error` for the next draw."""
        self.state = state
        self._cancel_all()
        future = self.worker.submit(self._apply, state)
        future.add_done_callback(self._keep_error)
        self._last_key = None        # the scene changed: the next request renders even for the same view

    def _keep_error(self, future) -> None:
        if future.exception() is not None:
            self.error = str(future.exception())

    def _cancel_all(self) -> None:
        with self._lock:
            for job in self._jobs:
                job.stop_requested.set()
            self._jobs = []

    def _apply(self, worker, state):
        if self._geometry is None:
            self._geometry = ViewportGeometry(worker.ctx)
        self._geometry.apply(state)

    @property
    def uploads(self) -> dict:
        """Times each mesh was uploaded (after the GPU thread has applied every sync so far)."""
        self.worker.submit(lambda worker: None).result()
        return dict(self._geometry.uploads) if self._geometry else {}

    # -- frames --------------------------------------------------------------------------------------------
    def request(self, camera: Camera, settings: RenderSettings, *, coarse_map: int = 256,
                coarse_scale: float = 0.5, progressive: bool = True) -> bool:
        """Ask for frames of this view; returns False when it is the view already on screen or in flight.
        Older frames still queued or running are cancelled."""
        key = (camera.view.tobytes(), camera.projection.tobytes(), camera.width, camera.height,
               repr(settings), coarse_map, coarse_scale, progressive)
        if key == self._last_key or self.state is None:
            return False
        settings.validate()
        self._last_key = key
        self._cancel_all()
        with self._lock:
            self._request += 1
            request = self._request
        plans = []
        if progressive:
            w, h = max(1, int(camera.width * coarse_scale)), max(1, int(camera.height * coarse_scale))
            plans.append((replace(camera, width=w, height=h), coarse_settings(settings, coarse_map), True))
        plans.append((camera, settings, False))
        for cam, s, coarse in plans:
            from ..gpu.context import Job
            job = Job()
            self._jobs.append(job)
            self.worker.submit(self._render, job, request, cam, s, coarse)
        return True

    def _render(self, worker, job, request, camera, settings, coarse):
        import time
        from . import pipeline
        if job.stop_requested.is_set() or self._geometry is None:
            self.cancelled += 1
            return None
        snap = SceneSnapshot(objects=self.state.objects, lights=self.state.lights, camera=camera,
                             name=self.state.name, warnings=list(self.state.warnings),
                             images=self.state.images, **SceneSnapshot.empty_geometry())
        start = time.perf_counter()
        # A sync (an object dragged) forgets the culling facts; working them out again costs up to a few
        # hundred ms on a large scene (SceneGeometry.culling_snapshot), which the coarse frame leaves to the
        # full one
        self._geometry.reads_facts = not coarse
        try:
            result = pipeline.render_job(worker, job, snap, settings, geometry=self._geometry)
        except Cancelled:
            self.cancelled += 1
            return None
        frame = ViewportFrame(result.passes, camera.width, camera.height, coarse, request,
                              (time.perf_counter() - start) * 1000.0, result.timings, result.warnings,
                              result.stats)
        with self._lock:
            if request == self._request and (self.latest is None or self.latest.request != request
                                             or not frame.coarse):
                self.latest = frame
        return frame

    def busy(self) -> bool:
        with self._lock:
            return self.latest is None or self.latest.request != self._request or self.latest.coarse

    def wait(self, timeout: float = 60.0) -> ViewportFrame | None:
        """Block until the newest request's full frame is done (tests and the benchmark)."""
        import time
        end = time.perf_counter() + timeout
        while self.busy() and time.perf_counter() < end:
            time.sleep(0.002)
        return self.latest

    def free(self) -> None:
        """Release GPU buffers (RenderEngine.__del__ / engine freed)."""
        self._cancel_all()
        geometry, self._geometry = self._geometry, None
        if geometry is not None:
            self.worker.submit(lambda worker: geometry.release())
