"""Scene geometry on the GPU, drawn through one interface whatever its layout.

`SoupGeometry` (final renders) holds the snapshot's world-space triangle soup in one vertex buffer, with
index buffers per role. The viewport's geometry (engine/render/viewport.py) keeps one object-space buffer per mesh
and draws instances with their model matrices, so moving an object uploads nothing. Shaders see the same
attributes either way (position, normal, albedo: 9 floats per vertex) plus u_model / u_normal_matrix.

Textured base colours (snapshot.textures): each image is uploaded once per frame; the soup's triangles are
ordered by texture within each role's index buffer, so one draw per texture binds it (with a sampler for the
node's interpolation and extension) and a second buffer carries the corners' texture coordinates (in_uv).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.snapshot import SUN, AlbedoTexture, SceneSnapshot
from .programs import set_uniforms

VERTEX_FORMAT = "3f 3f 3f"
ATTRIBUTES = ("in_position", "in_normal", "in_albedo")
IDENTITY4 = tuple(np.eye(4, dtype=np.float32).ravel())
IDENTITY3 = tuple(np.eye(3, dtype=np.float32).ravel())
ALBEDO_UNIT = 15                 # texture unit of the albedo image while the G-buffer draws
# u_albedo_map in glsl/common/gbuffer.frag: 0 no texture, else how coordinates outside [0, 1] read.
EXTENSION_MODES = {"REPEAT": 1, "EXTEND": 2, "CLIP": 3, "MIRROR": 4}
GL_NEAREST, GL_LINEAR = 0x2600, 0x2601


class AlbedoMap:
    """One snapshot texture on the GPU: the image (shared between maps of the same pixels) and a sampler."""

    def __init__(self, ctx, tex: AlbedoTexture, image):
        self.image = image
        self.srgb = tex.srgb
        self.mode = EXTENSION_MODES[tex.extension]
        self.sampler = ctx.sampler(repeat_x=tex.extension == "REPEAT", repeat_y=tex.extension == "REPEAT")
        f = GL_NEAREST if tex.interpolation == "Closest" else GL_LINEAR
        # No mipmaps: Cycles samples the image at each camera ray's hit, and Penumbra's is the pixel centre.
        self.sampler.filter = (f, f)
        if tex.extension == "CLIP":
            self.sampler.border_color = (0.0, 0.0, 0.0, 0.0)   # clamp to a black border, as Cycles' CLIP

    def use(self, prog):
        self.image.use(ALBEDO_UNIT)
        self.sampler.use(ALBEDO_UNIT)
        set_uniforms(prog, {"u_albedo_texture": ALBEDO_UNIT, "u_albedo_map": self.mode,
                            "u_albedo_srgb": int(self.srgb)})

    def release(self):
        self.sampler.release()


def upload_textures(ctx, textures: list[AlbedoTexture]) -> tuple[list[AlbedoMap], list, int]:
    """(maps, images, bytes): each distinct pixel array uploaded once, sRGB bytes as RGBA8 (decoded after
    filtering, in the shader), linear colours as RGBA16F."""
    images: dict[int, object] = {}
    maps, nbytes = [], 0
    for tex in textures:
        image = images.get(id(tex.pixels))
        if image is None:
            h, w = tex.pixels.shape[:2]
            byte = tex.pixels.dtype == np.uint8
            rgba = np.full((h, w, 4), 255 if byte else 1.0, np.uint8 if byte else np.float16)
            # Half floats end at 65504: brighter (HDR) texels are held there rather than turning infinite.
            rgba[..., :3] = tex.pixels if byte else np.clip(np.nan_to_num(tex.pixels), 0.0, 65504.0)
            image = images[id(tex.pixels)] = ctx.texture((w, h), 4, rgba.tobytes(), dtype="f1" if byte else "f2")
            nbytes += rgba.nbytes
        maps.append(AlbedoMap(ctx, tex, image))
    return maps, list(images.values()), nbytes


@dataclass
class Draw:
    vbo: object
    ibo: object | None          # None: draw the whole buffer
    vertices: int
    model: tuple = IDENTITY4     # column-major mat4
    normal: tuple = IDENTITY3    # column-major mat3 (cofactor of the model's 3×3, sign-fixed)
    mirrored: bool = False       # the model flips handedness: front faces wind the other way
    first: int = 0               # first index drawn
    texture: AlbedoMap | None = None   # albedo image bound while drawing (G-buffer), None: vertex albedo only
    uv: object | None = None     # buffer of 2 floats per vertex (in_uv), None: no texture coordinates


def texture_order(ids: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int, int]]]:
    """Triangles grouped by texture: (stable order of `ids`, [(texture id or -1, first, count)] in that order,
    counted in triangles), so one draw per texture binds it once."""
    order = np.argsort(ids, kind="stable")
    ids = ids[order]
    if ids.size == 0:
        return order, []
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    return order, [(int(ids[a]), int(a), int(b - a)) for a, b in zip(starts, ends)]


def _merged(draws: list[Draw]) -> list[Draw]:
    """Consecutive ranges of one buffer pair and transform as one draw (depth passes ignore textures)."""
    out: list[Draw] = []
    for d in draws:
        last = out[-1] if out else None
        if (last is not None and last.vbo is d.vbo and last.ibo is d.ibo and last.model == d.model
                and last.mirrored == d.mirrored and last.first + last.vertices == d.first):
            out[-1] = Draw(d.vbo, d.ibo, last.vertices + d.vertices, d.model, d.normal, d.mirrored, last.first)
        else:
            out.append(d)
    return out


def interleave(positions: np.ndarray, normals: np.ndarray, albedo: np.ndarray) -> bytes:
    """(T,3,3) positions and normals and (T,3) (per triangle) or (T,3,3) (per corner) albedo → the vertex
    buffer layout."""
    t = positions.shape[0]
    vertices = np.empty((t, 3, 9), np.float32)
    vertices[..., 0:3] = positions
    vertices[..., 3:6] = normals
    vertices[..., 6:9] = albedo if albedo.ndim == 3 else albedo[:, None, :]
    return vertices.tobytes()


class SceneGeometry:
    """What the frame needs from geometry: draws per role, per-object bounds, whether anything casts."""

    has_casters = False
    has_smooth = True           # some triangles are smooth-shaded (the G-buffer computes their terminator lift)

    def draws(self, role: str, objects: frozenset | None = None) -> list[Draw]:
        raise NotImplementedError

    def object_bounds(self) -> np.ndarray:
        raise NotImplementedError

    def culling_snapshot(self) -> SceneSnapshot | None:
        """The scene's triangles in world space, as the facts below are read from (None: none known)."""
        return None

    # Whether a frame may spend time working the facts out (a viewport's coarse frame, drawn while an object
    # is dragged, takes those known already, else none)
    reads_facts = True

    def _fact(self, name: str, read):
        """One culling fact, read once (until forget_facts) from culling_snapshot(), itself taken once."""
        facts = self.__dict__.setdefault("_facts", {})
        if name not in facts:
            if not self.reads_facts:
                return {}
            if "_facts_from" not in self.__dict__:
                self._facts_from = self.culling_snapshot()
            snap = self._facts_from
            facts[name] = read(snap) if snap is not None and snap.triangle_count else {}
        return facts[name]

    def forget_facts(self) -> None:
        self.__dict__.pop("_facts", None)
        self.__dict__.pop("_facts_from", None)

    def flat_objects(self) -> dict:
        """Flat objects' planes (SceneSnapshot.flat_objects)."""
        return self._fact("flat", lambda snap: snap.flat_objects())

    def convex_objects(self) -> dict:
        """Convex objects' face planes (SceneSnapshot.convex_objects); only those that can hold a light
        matter (lightview.receiver_sides)."""
        def read(snap):
            lights = [light.position for light in snap.lights if light.kind != SUN]
            return snap.convex_objects(around=lights, bounds=self.object_bounds()) if lights else {}
        return self._fact("convex", read)

    def coincident_sheets(self) -> dict:
        """Flattened closed casters, which Cycles shadows through their own faces (SceneSnapshot.coincident_sheets)."""
        return self._fact("sheets", lambda snap: snap.coincident_sheets())

    def convex_casters(self) -> dict:
        """Convex objects' face planes, whatever they hold (SceneSnapshot.convex_casters)."""
        return self._fact("convex_casters", lambda snap: snap.convex_casters)

    def light_clearances(self) -> dict:
        """Per local light (by name), a lower bound on the distance from its centre to the nearest triangle
        (SceneSnapshot.clearances, the triangles read once for every light): whether its ball holds any
        geometry (REFERENCE's soft-falloff samples)."""
        def read(snap):
            local = [light for light in snap.lights if light.kind != SUN]
            if not local:
                return {}
            distances = snap.clearances([light.position for light in local])
            return {light.name: float(d) for light, d in zip(local, distances)}
        return self._fact("clearance", read)

    def render(self, ctx, prog, role: str, objects: frozenset | None = None, position_only: bool = False):
        """Draw `role` ("receiver" or "caster"), optionally only the given object indices, with `prog`."""
        fmt = "3f 24x" if position_only else VERTEX_FORMAT
        attrs = ATTRIBUTES[:1] if position_only else ATTRIBUTES
        draws = self.draws(role, objects)
        textured = not position_only and "u_albedo_map" in prog
        takes_uv = textured and "in_uv" in prog
        if position_only:
            draws = _merged(draws)
        bound = []
        for d in draws:
            set_uniforms(prog, {"u_model": d.model, "u_normal_matrix": d.normal, "u_mirrored": int(d.mirrored)})
            content = [(d.vbo, fmt, *attrs)]
            if takes_uv and d.uv is not None:
                content.append((d.uv, "2f", "in_uv"))
            if textured:
                if d.texture is not None and d.uv is not None:
                    d.texture.use(prog)
                    bound.append(d.texture)
                else:
                    set_uniforms(prog, {"u_albedo_map": 0})
            if d.ibo is None:
                vao = ctx.vertex_array(prog, content)
            else:
                vao = ctx.vertex_array(prog, content, d.ibo, index_element_size=4)
            vao.render(vertices=d.vertices, first=d.first)
            vao.release()
        if bound:
            bound[-1].sampler.clear(ALBEDO_UNIT)   # later passes read this unit with their textures' own filters

    def release(self):
        pass


class SoupGeometry(SceneGeometry):
    """The snapshot's world-space triangles in one buffer; index buffers per role (and object filter)."""

    def __init__(self, ctx, snap: SceneSnapshot):
        self._ctx, self._snap = ctx, snap
        t = snap.triangle_count
        albedo = snap.albedo
        if snap.corner_color is not None:
            albedo = albedo[:, None, :] * snap.corner_color      # (T, 3, 3): per-corner colour
        self.vbo = ctx.buffer(interleave(snap.positions, snap.normals, albedo) if t else bytes(36))
        self._masks = {"receiver": snap.receiver_mask(), "caster": snap.caster_mask()}
        self.has_casters = bool(self._masks["caster"].any())
        self.has_smooth = snap.has_smooth_triangles
        self._ibos: dict = {}
        self._bounds = None
        self.nbytes = self.vbo.size
        self.uv = None
        self.maps, self._images = [], []
        if t and snap.texture_id is not None and snap.uv is not None and snap.textures:
            self.uv = ctx.buffer(np.ascontiguousarray(snap.uv, np.float32).tobytes())
            self.maps, self._images, image_bytes = upload_textures(ctx, snap.textures)
            self.nbytes += self.uv.size + image_bytes

    def draws(self, role, objects=None):
        key = (role, objects)
        if key not in self._ibos:
            mask = self._masks[role]
            if objects is not None:
                mask = mask & np.isin(self._snap.object_id, list(objects))
            tris = np.flatnonzero(mask)
            ranges = [(None, 0, 3 * tris.size)]
            if self.maps:
                order, groups = texture_order(self._snap.texture_id[tris])
                tris = tris[order]
                ranges = [(self.maps[i] if i >= 0 else None, 3 * first, 3 * n) for i, first, n in groups]
            corners = (3 * tris[:, None] + np.arange(3)).ravel().astype(np.uint32)
            ibo = self._ctx.buffer(corners.tobytes()) if corners.size else None
            self._ibos[key] = (ibo, ranges if corners.size else [])
        ibo, ranges = self._ibos[key]
        return [Draw(self.vbo, ibo, count, first=first, texture=tex, uv=self.uv) for tex, first, count in ranges]

    def object_bounds(self):
        if self._bounds is None:
            self._bounds = self._snap.object_bounds()
        return self._bounds

    def culling_snapshot(self):
        return self._snap

    def release(self):
        self.vbo.release()
        for ibo, _ in self._ibos.values():
            if ibo is not None:
                ibo.release()
        self._ibos.clear()
        for m in self.maps:
            m.release()
        for obj in self._images + ([self.uv] if self.uv is not None else []):
            obj.release()
        self.maps, self._images, self.uv = [], [], None
