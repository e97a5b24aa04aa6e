"""The interactive viewport: incremental scene sync, GPU-resident geometry, progressive and cancellable
frames.

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

from . import lightview
from .gpu.context import Cancelled, GpuWorker
from .gpu.geometry import Draw, SceneGeometry, interleave
from .settings import RenderSettings
from .snapshot import Camera, ObjectInfo, SceneSnapshot


# ---------------------------------------------------------------------------------------------------------
# scene side (bpy)
# ---------------------------------------------------------------------------------------------------------

@dataclass
class MeshPiece:
    """One mesh in object space, ready to upload: positions/normals (T,3,3), albedo (T,3), local bounds."""
    positions: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    version: int = 0

    @property
    def bounds(self) -> np.ndarray:
        flat = self.positions.reshape(-1, 3)
        return np.stack([flat.min(axis=0), flat.max(axis=0)]).astype(np.float64)


@dataclass
class Instance:
    key: tuple                  # MeshPiece key
    matrix: np.ndarray          # (4,4) object → world
    object_index: int


@dataclass
class SceneState:
    """What one viewport frame needs besides the GPU-resident meshes."""
    pieces: dict                # key → MeshPiece (only the ones that changed since the last sync are new)
    instances: list
    objects: list
    lights: list
    warnings: list
    name: str
    version: int


class ViewportScene:
    """Incremental depsgraph reader. `sync(depsgraph, updates)` returns the new state and the keys whose
    mesh data was (re)read; everything else is reused."""

    def __init__(self):
        self.pieces: dict[tuple, MeshPiece] = {}
        self.version = 0
        self.reads = 0          # meshes read from Blender since creation (tests count these)

    def sync(self, depsgraph, updates=None) -> tuple[SceneState, set]:
        """`updates`: depsgraph.updates of this change, or None to re-read every mesh."""
        import bpy
        from . import scene as extraction
        dirty_objects, dirty_meshes, materials_changed = set(), set(), updates is None
        for update in updates or ():
            idb = update.id
            if isinstance(idb, bpy.types.Object) and update.is_updated_geometry:
                dirty_objects.add(idb.name)
            elif isinstance(idb, bpy.types.Mesh):
                dirty_meshes.add(idb.name)
            elif isinstance(idb, (bpy.types.Material, bpy.types.NodeTree)):
                materials_changed = True
        warnings: list[str] = []
        objects: list[ObjectInfo] = []
        object_index: dict = {}
        instances: list[Instance] = []
        lights = []
        seen: set = set()
        changed: set = set()

        for inst in depsgraph.object_instances:
            ob = inst.object
            if ob.type == "LIGHT":
                lights.append(extraction.make_light(ob.name, ob.data, np.array(inst.matrix_world), warnings.append))
                continue
            if ob.type != "MESH" or (not inst.is_instance and not inst.show_self):
                continue
            parent = inst.parent if inst.is_instance else None
            key = (ob.name, ob.data.name)
            info = _object_info(ob, parent)
            oid = object_index.setdefault(info, len(objects))
            if oid == len(objects):
                objects.append(ObjectInfo(*info))
            if key not in seen:
                seen.add(key)
                stale = (key not in self.pieces or materials_changed or ob.name in dirty_objects
                         or ob.data.name in dirty_meshes)
                if stale:
                    piece = _read_piece(ob, extraction, warnings)
                    self.reads += 1
                    if piece is None:
                        self.pieces.pop(key, None)
                    else:
                        piece.version = self.version + 1
                        self.pieces[key] = piece
                    changed.add(key)
            if key in self.pieces:
                instances.append(Instance(key, np.array(inst.matrix_world, np.float64), oid))
        for key in set(self.pieces) - seen:        # deleted objects
            del self.pieces[key]
            changed.add(key)
        self.version += 1
        state = SceneState(dict(self.pieces), instances, objects, lights, warnings, depsgraph.scene.name,
                           self.version)
        return state, changed


def _object_info(ob, parent) -> tuple:
    caster, receiver = bool(ob.visible_shadow), bool(ob.visible_camera)
    role = str(getattr(getattr(ob, "penumbra", None), "role", "BOTH"))
    if parent is not None and parent != ob:
        caster = caster and bool(parent.visible_shadow)
        receiver = receiver and bool(parent.visible_camera)
    return (ob.name, caster, receiver, role)


def _read_piece(ob, extraction, warnings) -> MeshPiece | None:
    arrays = extraction.read_mesh(ob.data)
    if arrays is None:
        return None
    colors = [extraction.material_albedo(slot.material, warnings.append) for slot in ob.material_slots]
    table = np.array(colors or [extraction.GREY], np.float32).reshape(-1, 3)
    albedo = table[np.clip(arrays.mat, 0, len(table) - 1)]
    # The final render's clean-up, in object space: NaN/Inf and zero-area triangles dropped with a warning.
    geometry = extraction.sanitize(dict(positions=arrays.pos, normals=arrays.nrm.copy(), albedo=albedo,
                                         object_id=np.zeros(len(albedo), np.int32)),
                                    [ObjectInfo(ob.name)], warnings)
    if geometry["positions"].shape[0] == 0:
        return None
    return MeshPiece(np.ascontiguousarray(geometry["positions"]), np.ascontiguousarray(geometry["normals"]),
                     np.ascontiguousarray(geometry["albedo"]))


class UpdateRecorder:
    """Collects depsgraph.updates outside a viewport (benchmark, tests), in the form view_update sees them:
    a depsgraph_update_post handler while the recorder is open; `take()` applies pending edits and returns
    the updates since the last call."""

    class Update:
        def __init__(self, u):
            self.id = u.id.original if hasattr(u.id, "original") else u.id
            self.is_updated_geometry = u.is_updated_geometry
            self.is_updated_transform = u.is_updated_transform

    def __init__(self):
        import bpy
        self._batch: list = []
        bpy.app.handlers.depsgraph_update_post.append(self)

    def __call__(self, scene, depsgraph):
        self._batch.extend(self.Update(u) for u in depsgraph.updates)

    def take(self) -> list:
        import bpy
        bpy.context.view_layer.update()
        out, self._batch = self._batch, []
        return out

    def close(self) -> None:
        import bpy
        if self in bpy.app.handlers.depsgraph_update_post:
            bpy.app.handlers.depsgraph_update_post.remove(self)


# ---------------------------------------------------------------------------------------------------------
# GPU side
# ---------------------------------------------------------------------------------------------------------

class ViewportGeometry(SceneGeometry):
    """Object-space buffers per mesh, instances drawn with model matrices. Lives on the GPU thread."""

    def __init__(self, ctx):
        self._ctx = ctx
        self._buffers: dict[tuple, tuple] = {}     # key → (vbo, vertices, version, local bounds)
        self._instances: list[Instance] = []
        self._objects: list[ObjectInfo] = []
        self.uploads: dict[tuple, int] = {}        # key → times uploaded (tests count these)

    def apply(self, state: SceneState) -> None:
        for key in list(self._buffers):
            if key not in state.pieces:
                self._buffers.pop(key)[0].release()
        for key, piece in state.pieces.items():
            current = self._buffers.get(key)
            if current is not None and current[2] == piece.version:
                continue
            if current is not None:
                current[0].release()
            vbo = self._ctx.buffer(interleave(piece.positions, piece.normals, piece.albedo))
            self._buffers[key] = (vbo, 3 * piece.positions.shape[0], piece.version, piece.bounds)
            self.uploads[key] = self.uploads.get(key, 0) + 1
        self._instances, self._objects = state.instances, state.objects
        self.has_casters = any(self._objects[i.object_index].caster for i in self._instances)

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
            out.append(Draw(vbo, None, vertices, tuple(m.astype(np.float32).T.ravel()),
                            tuple(normal.astype(np.float32).T.ravel()), det < 0.0))
        return out

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
        self._buffers.clear()


# ---------------------------------------------------------------------------------------------------------
# session: progressive, cancellable frames
# ---------------------------------------------------------------------------------------------------------

def coarse_settings(settings: RenderSettings, map_size: int) -> RenderSettings:
    """The quick first frame after a change: a small map and the technique's own cheap mode
    (Technique.coarse)."""
    from .techniques import get
    changes = {"shadow_map_size": min(map_size, settings.shadow_map_size)}
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


class ViewportSession:
    """Owns the viewport's GPU geometry and the frames in flight. Call from Blender's main thread."""

    def __init__(self, worker: GpuWorker | None = None):
        self.worker = worker or GpuWorker.get()
        self.scene = ViewportScene()
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
    def sync(self, depsgraph, updates=None) -> set:
        """Read what changed (main thread), then hand the new meshes to the GPU thread without waiting:
        frames of the old scene are cancelled, and the GPU thread applies the upload before any newer frame
        (its queue is first in, first out). An upload error is kept in `error` for the next draw."""
        state, changed = self.scene.sync(depsgraph, updates)
        self.state = state
        self._cancel_all()
        future = self.worker.submit(self._apply, state)
        future.add_done_callback(self._keep_error)
        self._last_key = None        # the scene changed: the next request renders even for the same view
        return changed

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
            from .gpu.context import Job
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
                             **SceneSnapshot.empty_geometry())
        start = time.perf_counter()
        try:
            result = pipeline.render_job(worker, job, snap, settings, geometry=self._geometry)
        except Cancelled:
            self.cancelled += 1
            return None
        frame = ViewportFrame(result.passes, camera.width, camera.height, coarse, request,
                              (time.perf_counter() - start) * 1000.0, result.timings, result.warnings)
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
