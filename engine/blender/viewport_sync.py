"""The interactive viewport, Blender side (main thread): incremental depsgraph reading. A mesh is re-read only
when the depsgraph says its geometry (or a material) changed; transforms, lights and the camera touch no mesh.
`BlenderViewport` pairs this reader with the renderer's ViewportSession."""
from __future__ import annotations

import numpy as np

from ..core.snapshot import ObjectInfo
from ..core.viewport_state import Instance, MeshPiece, SceneState
from ..gpu.geometry import texture_order
from ..render.viewport import ViewportSession


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
        from . import extract as extraction
        dirty_objects, dirty_meshes, materials_changed = set(), set(), updates is None
        for update in updates or ():
            idb = update.id
            if isinstance(idb, bpy.types.Object) and update.is_updated_geometry:
                dirty_objects.add(idb.name)
            elif isinstance(idb, bpy.types.Mesh):
                dirty_meshes.add(idb.name)
            elif isinstance(idb, (bpy.types.Material, bpy.types.NodeTree, bpy.types.Image)):
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
            info = extraction.object_info(ob, parent)
            oid = object_index.setdefault(info, len(objects))
            new_object = oid == len(objects)
            if new_object:
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
                if new_object:      # its mesh's watertightness, read once with the piece, not on every sync
                    objects[oid].closed = self.pieces[key].closed
                instances.append(Instance(key, np.array(inst.matrix_world, np.float64), oid))
        for key in set(self.pieces) - seen:        # deleted objects
            del self.pieces[key]
            changed.add(key)
        self.version += 1
        state = SceneState(dict(self.pieces), instances, objects, lights, warnings, depsgraph.scene.name,
                           self.version, extraction.setting_images(depsgraph.scene))
        return state, changed


def _read_piece(ob, extraction, warnings) -> MeshPiece | None:
    arrays = extraction.read_mesh(ob.data)
    if arrays is None:
        return None
    # The final render's reading of materials: constant colours, images through UV maps, colour attributes.
    sources = tuple(extraction.material_albedo_source(slot.material, warnings.append)
                    for slot in ob.material_slots) or (extraction.CONSTANT_GREY,)
    if any(src.varies for src in sources):
        extraction.read_corner_layers(arrays, ob.data, sources, ob.name, warnings.append)
    textures = extraction.AlbedoTextures(warnings.append)
    albedo, varying = extraction.table_arrays(arrays, sources, textures)
    geometry = dict(positions=arrays.pos, normals=arrays.nrm.copy(), albedo=albedo,
                    object_id=np.zeros(len(albedo), np.int32))
    if varying is not None:
        texture_id, uv, corner_color = varying
        geometry.update(albedo=albedo[:, None, :] * corner_color, texture_id=texture_id, uv=uv)
    # The final render's clean-up, in object space: NaN/Inf and zero-area triangles dropped with a warning.
    geometry = extraction.sanitize(geometry, [ObjectInfo(ob.name)], warnings)
    if geometry["positions"].shape[0] == 0:
        return None
    uv, ranges = None, []
    if "texture_id" in geometry and (geometry["texture_id"] >= 0).any():
        order, ranges = texture_order(geometry["texture_id"])
        geometry = {k: v[order] for k, v in geometry.items()}
        uv = np.ascontiguousarray(geometry["uv"])
    return MeshPiece(np.ascontiguousarray(geometry["positions"]), np.ascontiguousarray(geometry["normals"]),
                     np.ascontiguousarray(geometry["albedo"]), uv=uv, ranges=ranges,
                     textures=textures.textures if ranges else [], closed=extraction.mesh_is_closed(ob.data))


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


class BlenderViewport(ViewportSession):
    """A ViewportSession fed from a depsgraph."""

    def __init__(self, worker=None):
        super().__init__(worker)
        self.scene = ViewportScene()

    def sync(self, depsgraph, updates=None) -> set:
        """Read what changed (main thread), then hand it to the GPU thread without waiting; returns the keys
        of the meshes that were (re)read."""
        state, changed = self.scene.sync(depsgraph, updates)
        self.apply_state(state)
        return changed
