"""Blender depsgraph -> `SceneSnapshot`. The only module that reads scene data through bpy.

Geometry comes from `depsgraph.object_instances`, so collection instances, geometry-nodes instances,
particles, curves, text, surfaces and metaballs all arrive as evaluated meshes (Blender converts the
latter into MESH instances itself). Each distinct evaluated mesh is read once with `foreach_get`, then
every instance of it is transformed in one batched numpy step.

Behaviour that mirrors Cycles (intern/cycles/blender/light.cpp, scene/light.cpp):
  * point/spot radius is `shadow_soft_size` as-is: Cycles does not scale it by the object transform;
  * area-light extents are `size * |local axis|` (object scale applies), spot cones keep the object scale
    in `spot_scale` (and, for skewed axes, the whole object map in `spot_linear`); a point light's scale and
    a sun's (but a zero Z) change nothing;
  * light colour is `color * temperature_color` when `use_temperature` is on (Blender's own blackbody
    value, read from RNA), power is `energy * 2**exposure`;
  * a light with "Normalize" off is folded into `power` by multiplying with its emitting area, which is
    what Cycles effectively does (it skips the 1/area factor), so `power` keeps meaning watts;
  * lights Cycles renders no light from get power 0 and a warning (measured: tests/test_irradiance_cycles.py):
    a zero-size area light (size or X/Y object scale 0), an area light or a sun with a zero Z scale (no
    emission direction), a spot with a zero X or Y scale. A point light with zero scale still shines, as in
    Cycles; a spot with a zero Z scale lights a half-space (`_singular_spot`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.irradiance import spot_edge_tans
from ..core.snapshot import (AREA, ELLIPSE, POINT, RECTANGLE, SPOT, SUN, AlbedoTexture, Camera, Light, ObjectInfo,
                             SceneSnapshot)

GREY = (0.8, 0.8, 0.8)
# A triangle is dropped when its area is below this fraction of the squared scene diagonal.
REL_AREA_EPS = 1e-12


# ----------------------------------------------------------------------------------------------------------
# small numeric helpers (bpy-free)
# ----------------------------------------------------------------------------------------------------------

def _unit(v: np.ndarray, fallback) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not math.isfinite(n) or n < 1e-30:
        return np.asarray(fallback, dtype=np.float64)
    return v / n


def orthonormal_frame(m: np.ndarray, primary: int = 2, secondary: int = 0) -> np.ndarray:
    """Right-handed orthonormal copy of a 4x4 affine matrix: axis `primary` keeps its direction, axis
    `secondary` is made perpendicular to it (Gram-Schmidt), the third axis completes a right-handed frame.
    Translation is kept. Degenerate (zero-scale) axes fall back to the identity axes."""
    m = np.asarray(m, dtype=np.float64)
    out = np.eye(4)
    eye = np.eye(3)
    a = _unit(m[:3, primary].copy(), eye[primary])
    b = m[:3, secondary] - np.dot(m[:3, secondary], a) * a
    # A zero secondary axis falls back to the identity's, made perpendicular to `a` and unit length (left
    # unnormalised, a sun with a zero X scale had X and Y axes of length 0.71 and its samples a narrower cone)
    b = _unit(b, _unit(eye[secondary] - np.dot(eye[secondary], a) * a, np.zeros(3)))
    if np.linalg.norm(b) < 0.5:  # fallback axis parallel to `a`: take any perpendicular
        helper = eye[np.argmin(np.abs(a))]
        b = _unit(helper - np.dot(helper, a) * a, helper)
    third = 3 - primary - secondary
    # Right-handed: x = y × z, y = z × x, z = x × y.
    axes = {primary: a, secondary: b}
    nxt = {0: (1, 2), 1: (2, 0), 2: (0, 1)}[third]
    axes[third] = np.cross(axes[nxt[0]], axes[nxt[1]])
    for i in range(3):
        out[:3, i] = axes[i]
    out[:3, 3] = m[:3, 3]
    return out


def _matrix_np(mat) -> np.ndarray:
    """mathutils.Matrix -> (4, 4) float64 array (rows as Blender stores them)."""
    return np.array(mat, dtype=np.float64)


def _stack_matrices(mats: list) -> np.ndarray:
    """List of 4x4 mathutils.Matrix -> (K, 4, 4) float64. Goes through the buffer protocol (bytes() gives
    the logical row-major float32 layout), several times faster than np.array(list) for 100k matrices."""
    raw = b"".join(map(bytes, mats))
    if len(raw) == 64 * len(mats):
        return np.frombuffer(raw, np.float32).reshape(-1, 4, 4).astype(np.float64)
    return np.array(mats, dtype=np.float64).reshape(-1, 4, 4)


# ----------------------------------------------------------------------------------------------------------
# meshes
# ----------------------------------------------------------------------------------------------------------

class _MeshArrays:
    __slots__ = ("pos", "nrm", "mat", "loops", "tri_verts", "uv", "colors")

    def __init__(self, pos, nrm, mat, loops=None, tri_verts=None):
        self.pos = pos          # (t, 3, 3) float32, object space
        self.nrm = nrm          # (t, 3, 3) float32, object space corner normals
        self.mat = mat          # (t,) int32 material index (unclamped)
        self.loops = loops      # (3t,) corner (loop) index of each triangle corner
        self.tri_verts = tri_verts  # (3t,) vertex index of each triangle corner
        self.uv = {}            # UV map name ("" = active render) -> (t, 3, 2) float32, read on demand
        self.colors = {}        # colour attribute name ("" = active render) -> (t, 3, 3) float32, on demand


def _read_int_attribute(mesh, name: str, domain: str, count: int):
    attr = mesh.attributes.get(name)
    if attr is None or attr.domain != domain or attr.data_type != "INT" or len(attr.data) != count:
        return None
    out = np.empty(count, np.int32)
    attr.data.foreach_get("value", out)
    return out


def mesh_is_closed(mesh) -> bool:
    """Every edge of `mesh` joins exactly two faces (a watertight surface, as a flattened solid's coincident
    sheets need: SceneSnapshot.coincident_sheets)."""
    if not len(mesh.polygons) or not len(mesh.edges):
        return False
    edge_index = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("edge_index", edge_index)
    return bool(np.all(np.bincount(edge_index, minlength=len(mesh.edges)) == 2))


def read_mesh(mesh) -> _MeshArrays | None:
    """Triangulated local arrays of an evaluated mesh, bulk reads only. None for an empty mesh.

    The dtypes matter: `loop_triangles.foreach_get('loops', …)` has a raw-copy fast path only for uint32
    buffers (about 100x faster than int32 at 1M triangles)."""
    tris = mesh.loop_triangles
    nt = len(tris)
    if nt == 0:
        return None
    nv, nl = len(mesh.vertices), len(mesh.loops)

    loops = np.empty(nt * 3, np.uint32)
    tris.foreach_get("loops", loops)

    co = np.empty(nv * 3, np.float32)
    pos_attr = mesh.attributes.get("position")
    if pos_attr is not None and pos_attr.data_type == "FLOAT_VECTOR" and len(pos_attr.data) == nv:
        pos_attr.data.foreach_get("vector", co)
    else:
        mesh.vertices.foreach_get("co", co)
    co = co.reshape(nv, 3)

    corner_vert = _read_int_attribute(mesh, ".corner_vert", "CORNER", nl)
    if corner_vert is not None:
        tri_verts = np.take(corner_vert, loops)
    else:
        tri_verts = np.empty(nt * 3, np.uint32)
        tris.foreach_get("vertices", tri_verts)

    cn = np.empty(nl * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", cn)
    cn = cn.reshape(nl, 3)

    tri_poly = None

    def triangle_faces():
        nonlocal tri_poly
        if tri_poly is None:
            tri_poly = np.empty(nt, np.int32)
            mesh.loop_triangle_polygons.foreach_get("value", tri_poly)
        return tri_poly

    face_mat = _read_int_attribute(mesh, "material_index", "FACE", len(mesh.polygons))
    mat = np.zeros(nt, np.int32) if face_mat is None else np.take(face_mat, triangle_faces())

    pos = np.take(co, tri_verts, axis=0).reshape(nt, 3, 3)
    nrm = np.take(cn, loops, axis=0).reshape(nt, 3, 3)
    flat = _flat_triangles(mesh, triangle_faces)
    if flat is not None:
        nrm[flat] = _triangle_normals(pos[flat])[:, None, :]
    return _MeshArrays(pos, nrm, mat, loops, tri_verts)


def _flat_triangles(mesh, triangle_faces):
    """Triangles of flat-shaded faces: a bool mask, or None when every face is smooth. Cycles shades a flat
    triangle with its own geometric normal (not the face normal Blender's corner normals carry, which differs
    on a non-planar quad or n-gon), and a face is flat when its `sharp_face` is set or, without that
    attribute, when every edge is sharp (normals domain FACE)."""
    sharp = mesh.attributes.get("sharp_face")
    if sharp is not None and sharp.domain == "FACE" and sharp.data_type == "BOOLEAN" \
            and len(sharp.data) == len(mesh.polygons):
        faces = np.empty(len(mesh.polygons), bool)
        sharp.data.foreach_get("value", faces)
        if not faces.any():
            return None
        return np.take(faces, triangle_faces())
    if mesh.normals_domain == "FACE":
        return np.ones(len(mesh.loop_triangles), bool)
    return None


def _triangle_normals(pos: np.ndarray) -> np.ndarray:
    """Unit geometric normals (..., 3) of triangles (..., 3, 3), counter-clockwise front; zero for a
    degenerate triangle (sanitize repairs or drops it later)."""
    n = np.cross(pos[..., 1, :] - pos[..., 0, :], pos[..., 2, :] - pos[..., 0, :])
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0).astype(np.float32)


def read_corner_layers(arrays: _MeshArrays, mesh, sources, owner: str, warn) -> None:
    """Read the UV maps and colour attributes that `sources` (AlbedoSource) sample, per triangle corner,
    into `arrays` (once per mesh and name). A missing layer reads as zeros (black), with a warning."""
    nt = arrays.pos.shape[0]
    for src in sources:
        if src.image_key and src.uv_map not in arrays.uv:
            layers = mesh.uv_layers
            layer = layers.get(src.uv_map) if src.uv_map else next((l for l in layers if l.active_render), None)
            uv = np.zeros((nt, 3, 2), np.float32)
            if layer is None:
                warn(f"object '{owner}' has no UV map {repr(src.uv_map) if src.uv_map else ''}: "
                     f"its texture is read at (0, 0)")
            else:
                per_loop = np.empty(len(mesh.loops) * 2, np.float32)
                layer.uv.foreach_get("vector", per_loop)
                uv = np.take(per_loop.reshape(-1, 2), arrays.loops, axis=0).reshape(nt, 3, 2)
            arrays.uv[src.uv_map] = uv
        if src.attribute is not None and src.attribute not in arrays.colors:
            attrs = mesh.color_attributes
            attr = attrs.get(src.attribute) if src.attribute else None
            if not src.attribute and 0 <= attrs.render_color_index < len(attrs):
                attr = attrs[attrs.render_color_index]
            col = np.zeros((nt, 3, 3), np.float32)
            if attr is None or attr.domain not in ("POINT", "CORNER"):
                warn(f"object '{owner}' has no colour attribute {repr(src.attribute) if src.attribute else ''} "
                     f"on points or corners: read as black")
            else:
                rgba = np.empty(len(attr.data) * 4, np.float32)
                attr.data.foreach_get("color", rgba)       # linear for byte and float colours alike
                index = arrays.loops if attr.domain == "CORNER" else arrays.tri_verts
                col = np.take(rgba.reshape(-1, 4)[:, :3], index, axis=0).reshape(nt, 3, 3)
            arrays.colors[src.attribute] = col


def transform_instances(arrays: _MeshArrays, matrices: np.ndarray):
    """World positions and normals of K instances of one mesh. matrices: (K, 4, 4). Returns
    pos (K*t, 3, 3) float32, nrm (K*t, 3, 3) float32, flipped (K,) bool (det < 0: corners 1, 2 swapped)."""
    k = matrices.shape[0]
    t = arrays.pos.shape[0]
    rot = matrices[:, :3, :3].astype(np.float32)
    a, b, c = rot[:, :, 0], rot[:, :, 1], rot[:, :, 2]
    # Cofactor matrix, columns (b×c, c×a, a×b) = det · R^-T. It stays meaningful for singular R (a zero
    # scale axis flattens normals onto that axis instead of producing NaN), so no inverse is needed.
    cof = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=2)
    det = np.einsum("ki,ki->k", a, cof[:, :, 0])
    flipped = det < 0
    cof[flipped] *= -1.0
    # A scale axis at 0 (a flattened object): the cofactor maps every normal onto ±(the flattening axis) by
    # the sign of its component there, so a smooth surface's corners point up and down at random and whole
    # triangles average to nothing. Such instances take the normal of the flattened triangle itself.
    scale3 = np.prod(np.linalg.norm(rot, axis=1) + 1e-30, axis=1)   # |det| ≤ product of the row norms
    singular = np.abs(det) <= 1e-6 * scale3
    if singular.any():
        pos = np.matmul(arrays.pos.reshape(1, t * 3, 3), rot.transpose(0, 2, 1))
        pos += matrices[:, None, :3, 3].astype(np.float32)
        pos = pos.reshape(k, t, 3, 3)
        nrm = np.matmul(arrays.nrm.reshape(1, t * 3, 3), cof.transpose(0, 2, 1)).reshape(k, t, 3, 3)
        face = _triangle_normals(pos[singular])
        nrm[singular] = face[:, :, None, :]         # zero where the triangle itself collapsed (dropped later)
        rest = ~singular
        if rest.any():
            n = nrm[rest].reshape(-1, 3)
            ln = np.sqrt(np.einsum("ij,ij->i", n, n))[:, None]
            np.divide(n, ln, out=n, where=ln > 0)
            nrm[rest] = n.reshape(-1, t, 3, 3)
        return _flip(pos, nrm, flipped) + (flipped,)
    # Row vectors: p'^T = p^T R^T + T, n'^T ∝ n^T cof^T.
    if k == 1:
        r, tr = rot[0], matrices[0, :3, 3].astype(np.float32)
        if np.array_equal(r, np.eye(3, dtype=np.float32)):
            pos = arrays.pos.reshape(-1, 3) + tr
            nrm = arrays.nrm.reshape(-1, 3).copy()
            return pos.reshape(t, 3, 3), nrm.reshape(t, 3, 3), flipped
        pos = arrays.pos.reshape(-1, 3) @ r.T + tr
        gram = cof[0].T @ cof[0]
        scale2 = float(np.trace(gram)) / 3.0
        if scale2 > 0 and np.abs(gram - scale2 * np.eye(3)).max() <= 1e-5 * scale2:
            # Rotation times uniform scale: one matrix maps unit normals to unit normals.
            nrm = arrays.nrm.reshape(-1, 3) @ (cof[0].T / np.float32(math.sqrt(scale2)))
            return _flip(pos.reshape(1, t, 3, 3), nrm.reshape(1, t, 3, 3), flipped) + (flipped,)
        nrm = arrays.nrm.reshape(-1, 3) @ cof[0].T
    else:
        pos = np.matmul(arrays.pos.reshape(1, t * 3, 3), rot.transpose(0, 2, 1))
        pos += matrices[:, None, :3, 3].astype(np.float32)
        nrm = np.matmul(arrays.nrm.reshape(1, t * 3, 3), cof.transpose(0, 2, 1))
    nrm = nrm.reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", nrm, nrm))[:, None]
    np.divide(nrm, length, out=nrm, where=length > 0)
    return _flip(pos.reshape(k, t, 3, 3), nrm.reshape(k, t, 3, 3), flipped) + (flipped,)


def _flip(pos, nrm, flipped):
    """Swap corners 1 and 2 of mirrored instances so winding stays counter-clockwise from the front."""
    k, t = pos.shape[:2]
    if flipped.any():
        swap = [0, 2, 1]
        if flipped.all():
            pos = pos[:, :, swap]
            nrm = nrm[:, :, swap]
        else:
            pos[flipped] = pos[flipped][:, :, swap]
            nrm[flipped] = nrm[flipped][:, :, swap]
    return pos.reshape(k * t, 3, 3), nrm.reshape(k * t, 3, 3)


# ----------------------------------------------------------------------------------------------------------
# materials
# ----------------------------------------------------------------------------------------------------------

def _follow_reroutes(socket):
    """The node feeding `socket` (through reroutes and muted-free links), or None."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if getattr(link, "is_muted", False) or not getattr(link, "is_valid", True):
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            seen += 1
            continue
        return node, link.from_socket
    return None


@dataclass(frozen=True)
class AlbedoSource:
    """Where a material's diffuse colour comes from: a constant, an image sampled through a UV map, or a
    colour attribute. Equal sources (same image, map, mapping and settings) compare equal."""

    color: tuple = GREY                 # the constant colour; (1, 1, 1) when an image or attribute gives it
    image_key: int = 0                  # as_pointer() of the image, 0: no image
    uv_map: str = ""                    # UV map name, "": the mesh's active render map
    uv_matrix: tuple | None = None      # ((a, b, c), (d, e, f)): (u, v) -> (a u + b v + c, d u + e v + f)
    interpolation: str = "Linear"
    extension: str = "REPEAT"
    attribute: str | None = None        # colour attribute name ("": the active render one); None: none
    image: object = field(default=None, compare=False, hash=False)   # the bpy Image itself
    description: str = field(default="", compare=False, hash=False)  # how the colour is read, for the UI

    @property
    def varies(self) -> bool:
        """True when the colour changes over the surface (per-corner data is needed)."""
        return self.image_key != 0 or self.attribute is not None


CONSTANT_GREY = AlbedoSource(GREY, description="0.8 grey")
_INTERPOLATIONS = {"Linear": "Linear", "Closest": "Closest", "Cubic": "Linear", "Smart": "Linear"}


def _output_node(tree):
    get_output = getattr(tree, "get_output_node", None)
    out = (get_output("CYCLES") or get_output("ALL")) if get_output is not None else None
    if out is None:
        outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
        out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
    return out


def _node_label(node) -> str:
    return f"node '{node.name}' ({node.bl_idname})"


def material_albedo_source(mat, warn) -> AlbedoSource:
    """How the diffuse colour of `mat` is read (Cycles' node tree; see `_color_source` for the nodes
    understood). `warn(text)` is called, naming the material and node, for anything not read."""
    if mat is None:
        return CONSTANT_GREY
    diffuse = tuple(float(c) for c in mat.diffuse_color[:3])
    tree = mat.node_tree
    out = _output_node(tree) if tree is not None else None
    if out is None:
        return AlbedoSource(diffuse, description="viewport display colour (no node tree)")
    fed = _follow_reroutes(out.inputs.get("Surface"))
    if fed is None:
        # Cycles renders an unconnected surface as black; treat as the neutral grey but say so.
        warn(f"material '{mat.name}': no surface shader connected, using 0.8 grey")
        return CONSTANT_GREY
    node, _ = fed
    if node.bl_idname == "ShaderNodeBsdfPrincipled":
        sock = node.inputs.get("Base Color")
    elif node.bl_idname == "ShaderNodeBsdfDiffuse":
        sock = node.inputs.get("Color")
    else:
        warn(f"material '{mat.name}': surface shader {_node_label(node)} is not supported, using 0.8 grey")
        return CONSTANT_GREY
    if sock is None:
        return CONSTANT_GREY
    if not sock.is_linked:
        return AlbedoSource(tuple(float(c) for c in sock.default_value[:3]), description="constant colour")
    source, problem = _color_source(_follow_reroutes(sock))
    if source is None:
        warn(f"material '{mat.name}': base colour {problem}, which Penumbra does not read: using 0.8 grey")
        return CONSTANT_GREY
    if problem:
        warn(f"material '{mat.name}': {problem}")
    return source


def _color_source(fed) -> tuple[AlbedoSource | None, str]:
    """(source, note) for the node output feeding a base colour; (None, what it is) when not read.

    Read: RGB node; Image Texture (Flat projection, image from a file or generated/packed, Color output)
    whose Vector comes from nothing (the active UV map), a UV Map node, Texture Coordinate's UV output, or
    any chain of Mapping nodes (Point, Texture or Vector type, unlinked settings) ending in one of those;
    Color Attribute node; Attribute node (Geometry type, Color output) naming a colour attribute."""
    if fed is None:
        return None, "comes from a muted or invalid link"
    node, out_socket = fed
    kind = node.bl_idname
    if kind == "ShaderNodeRGB":
        return AlbedoSource(tuple(float(c) for c in node.outputs[0].default_value[:3]),
                            description="RGB node"), ""
    if kind == "ShaderNodeVertexColor" and out_socket.name == "Color":
        name = str(node.layer_name)
        return AlbedoSource((1.0, 1.0, 1.0), attribute=name,
                            description=f"colour attribute '{name or '(active render)'}'"), ""
    if (kind == "ShaderNodeAttribute" and out_socket.name == "Color" and node.attribute_type == "GEOMETRY"
            and node.attribute_name):
        name = str(node.attribute_name)
        return AlbedoSource((1.0, 1.0, 1.0), attribute=name, description=f"colour attribute '{name}'"), ""
    if kind != "ShaderNodeTexImage":
        return None, f"comes from {_node_label(node)}"
    image = node.image
    if out_socket.name != "Color":
        return None, f"comes from the {out_socket.name} output of {_node_label(node)}"
    if image is None:
        return None, f"comes from {_node_label(node)} without an image"
    if image.source not in ("FILE", "GENERATED"):
        return None, f"comes from {_node_label(node)} with a {image.source} image ('{image.name}')"
    if node.projection != "FLAT":
        return None, f"comes from {_node_label(node)} with {node.projection} projection"
    if image.size[0] == 0 or image.size[1] == 0:
        return None, f"comes from image '{image.name}' which has no pixels (file missing?)"
    uv_map, matrix, problem = _uv_chain(node.inputs["Vector"])
    if problem:
        return None, f"comes from {_node_label(node)} whose Vector {problem}"
    note = ""
    interpolation = _INTERPOLATIONS.get(node.interpolation, "Linear")
    if interpolation != node.interpolation:
        note = f"{_node_label(node)}: {node.interpolation} interpolation is read as Linear"
    extension = node.extension if node.extension in ("REPEAT", "EXTEND", "CLIP", "MIRROR") else "REPEAT"
    where = f"UV map '{uv_map}'" if uv_map else "the active UV map"
    return AlbedoSource((1.0, 1.0, 1.0), image_key=image.as_pointer(), uv_map=uv_map, uv_matrix=matrix,
                        interpolation=interpolation, extension=extension, image=image,
                        description=f"image '{image.name}' through {where}"
                                    f"{' and a Mapping' if matrix is not None else ''}"), note


def _uv_chain(socket):
    """(uv map name, 2x3 affine matrix or None, problem) for an Image Texture's Vector input."""
    m = np.eye(3)
    while True:
        if not socket.is_linked:
            if socket.node.bl_idname == "ShaderNodeTexImage":
                return "", _affine_or_none(m), ""
            return "", None, f"ends at an unlinked {_node_label(socket.node)}"
        fed = _follow_reroutes(socket)
        if fed is None:
            return "", None, "has a muted or invalid link"
        node, out = fed
        if node.bl_idname == "ShaderNodeUVMap":
            return str(node.uv_map), _affine_or_none(m), ""
        if node.bl_idname == "ShaderNodeTexCoord" and out.name == "UV":
            return "", _affine_or_none(m), ""
        if node.bl_idname == "ShaderNodeMapping":
            step = _mapping_matrix(node)
            if step is None:
                return "", None, f"goes through {_node_label(node)} of type {node.vector_type} or with linked settings"
            m = m @ step
            socket = node.inputs["Vector"]
            continue
        return "", None, f"comes from the {out.name} output of {_node_label(node)}"


def _affine_or_none(m):
    if np.allclose(m, np.eye(3), rtol=0.0, atol=1e-12):
        return None
    return tuple(tuple(float(x) for x in row) for row in m[:2])


def _mapping_matrix(node):
    """3x3 affine matrix of a Mapping node on (u, v, 1) (w = 0 in, z dropped out), or None if unsupported.

    Blender's Mapping node: Point p' = T + R (S p); Texture p' = S^-1 (R^-1 (p - T)); Vector p' = R (S p),
    with R the XYZ Euler rotation. Texture coordinates come in with z = 0, so only the x, y rows and the
    u, v columns of the 3D transform matter."""
    from mathutils import Euler

    kind = node.vector_type
    if kind not in ("POINT", "TEXTURE", "VECTOR"):
        return None
    names = ["Rotation", "Scale"] + (["Location"] if kind != "VECTOR" else [])
    if any(node.inputs[n].is_linked for n in names):
        return None
    rot = np.array(Euler(tuple(node.inputs["Rotation"].default_value), "XYZ").to_matrix(), float)
    scale = np.array(node.inputs["Scale"].default_value, float)
    loc = np.array(node.inputs["Location"].default_value, float) if kind != "VECTOR" else np.zeros(3)
    full = np.eye(4)
    if kind == "TEXTURE":
        if np.any(scale == 0.0):
            return None
        full[:3, :3] = np.diag(1.0 / scale) @ rot.T
        full[:3, 3] = -full[:3, :3] @ loc
    else:
        full[:3, :3] = rot @ np.diag(scale)
        full[:3, 3] = loc
    out = np.eye(3)
    out[:2, :2] = full[:2, :2]
    out[:2, 2] = full[:2, 3]
    return out


# ----------------------------------------------------------------------------------------------------------
# lights
# ----------------------------------------------------------------------------------------------------------

# Axes whose normalised dot product exceeds this count as not perpendicular (a sheared light transform).
SHEAR_EPS = 1e-5


def sheared_axes(matrix: np.ndarray) -> bool:
    """Whether the nonzero axes of a 4×4 object matrix's linear part are not mutually perpendicular: the
    world matrix of an object under a rotated, non-uniformly scaled parent. Zero axes are left to the
    singular-scale rules."""
    axes = np.asarray(matrix, np.float64)[:3, :3]
    norms = np.linalg.norm(axes, axis=0)
    unit = axes[:, norms > 0.0] / norms[norms > 0.0]
    gram = unit.T @ unit
    return bool(np.abs(gram - np.eye(len(gram))).max() > SHEAR_EPS)


def make_light(name: str, light, matrix: np.ndarray, warn) -> Light:
    """Snapshot light from a bpy Light datablock and its instance world matrix (4x4 numpy). `warn(text)`
    receives anything the snapshot cannot represent exactly."""
    kind = light.type
    scale = np.linalg.norm(matrix[:3, :3], axis=0)  # |local X|, |local Y|, |local Z|
    color = np.array(light.color[:3], dtype=np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.array(light.temperature_color[:3], dtype=np.float64)
    power = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    normalize = bool(getattr(light, "normalize", True))
    out = Light(name=name, kind=kind, matrix=orthonormal_frame(matrix, 2, 0), color=color, power=power,
                casts_shadow=bool(light.use_shadow))
    if kind == AREA:
        out.shape = light.shape
        size_y = light.size_y if light.shape in (RECTANGLE, ELLIPSE) else light.size
        out.size_x = float(light.size * scale[0])
        out.size_y = float(size_y * scale[1])
        if out.size_x <= 0.0 or out.size_y <= 0.0:
            warn(f"area light '{name}' has zero size: Cycles renders no light from it, and neither does Penumbra")
            out.power = 0.0
        elif scale[2] <= 0.0:
            warn(f"area light '{name}' has a zero Z scale (no emission direction): Cycles renders no light "
                 "from it, and neither does Penumbra")
            out.power = 0.0
        out.texture = light_texture(light, warn)
        if out.texture is not None and np.linalg.det(np.asarray(matrix, np.float64)[:3, :3]) < 0.0:
            # Cycles' image follows the object's own Y axis (kernel/light/area.h: v = dot(P, axis_v)), which a
            # mirrored matrix points against the right-handed frame's Y: its rows run the other way there.
            out.texture = out.texture[::-1].copy()
        if out.texture is not None:
            mean = out.texture.reshape(-1, 3).mean(axis=0)
            out.color = out.color * mean
            out.texture = (out.texture / np.maximum(mean, 1e-12)).astype(np.float32)
        if out.power > 0.0 and sheared_axes(matrix):
            # Cycles keeps the skewed axes and samples them as a rectangle with perpendicular sides
            # (kernel/light/area.h, area_light_rect_sample), around an emission axis that may leave the
            # light's plane: measured 2.6x Penumbra's light on the receivers of a 40° skew.
            warn(f"area light '{name}' has skewed axes (its X, Y and Z are not perpendicular, from a rotated "
                 "non-uniformly scaled parent): Cycles' light from it is not a true parallelogram, Penumbra "
                 "renders a rectangle of the same side lengths")
        if float(getattr(light, "spread", math.pi)) < math.pi - 1e-6:
            warn(f"area light '{name}' has a spread below 180°: rendered with the full 180° spread")
    elif kind in (POINT, SPOT):
        out.radius = float(light.shadow_soft_size)
        out.use_soft_falloff = bool(getattr(light, "use_soft_falloff", True))
        if kind == SPOT:
            out.spot_size = float(light.spot_size)
            out.spot_blend = float(light.spot_blend)
            out.spot_scale = scale.copy()
            if getattr(light, "use_square", False):
                warn(f"spot light '{name}' has a square cone: rendered with a round cone")
            _singular_spot(name, out, matrix, scale, warn)
            if not out.spot_axisless and out.power > 0.0 and sheared_axes(matrix):
                # Cycles' cone is the image of a round cone under the object map, skewed axes included
                # (Light.spot_to_local): kept exactly as that map in the light's frame.
                linear = out.matrix[:3, :3].T @ np.asarray(matrix, np.float64)[:3, :3]
                if abs(np.linalg.det(linear)) <= 1e-9 * float(np.prod(scale)):
                    warn(f"spot light '{name}' has its three axes in one plane (a flattened, rotated parent): "
                         "Cycles' cone through that singular matrix is not modelled, Penumbra uses the cone of "
                         "its axes' lengths")
                else:
                    out.spot_linear = linear
                    _skewed_spot_reach(name, out, scale, warn)
    elif kind == SUN:
        out.angle = float(light.angle)
        if scale[2] <= 0.0:
            warn(f"sun '{name}' has a zero Z scale (no direction): Cycles renders no light from it, and neither "
                 "does Penumbra")
            out.power = 0.0
    if not normalize:
        # Cycles divides by the emitting area only when Normalize is on; fold the difference into power.
        if kind == AREA:
            area = out.area
        elif kind in (POINT, SPOT):
            area = 4.0 * math.pi * out.radius ** 2 or 1.0     # a radius-0 point is unaffected
        elif kind == SUN:
            area = math.pi * math.sin(out.angle / 2.0) ** 2 if out.angle > 0 else 1.0
        else:
            area = 1.0
        out.power *= area
    return out


def _skewed_spot_reach(name: str, out: Light, scale: np.ndarray, warn) -> None:
    """Cycles' light tree bounds a spot's emission by the cone of half angle atan(tan(spot_size/2) ·
    max(|X|, |Y|) / |Z|) around its Z axis (scene/light_tree.cpp), exact for perpendicular axes. A skewed
    cone reaches past it, and there only BSDF rays that happen to hit the emitter light a receiver: sparse
    fireflies that converge to the whole cone, which is what Penumbra renders (measured: tests/
    test_irradiance_cycles.py, test_skewed_spot)."""
    tree = math.degrees(math.atan(math.tan(min(out.spot_size / 2.0, math.pi / 2.0 - 1e-6))
                                  * max(scale[0], scale[1]) / scale[2]))
    cone = math.degrees(math.atan(spot_edge_tans(out)[2]))
    if cone > tree + 0.5:
        warn(f"spot light '{name}' has skewed axes (a rotated, non-uniformly scaled parent): its cone reaches "
             f"{cone:.0f}° off its Z axis, Cycles' light tree only {tree:.0f}°; beyond that Cycles renders "
             "sparse fireflies that converge to the light Penumbra renders")


def _singular_spot(name: str, out: Light, matrix: np.ndarray, scale: np.ndarray, warn) -> None:
    """A spot whose object scale has a zero axis, as Cycles renders it. Cycles takes each ray to the spot's
    frame with the inverse object matrix (kernel/light/spot.h), and inverts a singular matrix by adding 1e-8
    to its diagonal (util/transform.h, transform_inverse_impl). A zero X or Y axis then blows that local
    coordinate up, the ray's local z goes to 0 and the cone's smoothstep to 0: no light. A zero Z axis
    becomes (0, 0, 1e-8), so the local z of every ray is ±1 by the side of the light's X/Y plane it leaves
    on: the cone opens to the whole half-space on the side of that plane that world -Z points into (the
    sign of the tweak), whatever the light's own direction; and its light-tree importance, built on the
    zero emission axis, vanishes where float32 no longer resolves the radius (`spot_axisless`).
    Measured: tests/test_irradiance_cycles.py (an all-zero scale renders black too)."""
    if scale[0] <= 0.0 or scale[1] <= 0.0:
        warn(f"spot light '{name}' has a zero X or Y scale: Cycles renders no light from it, and neither "
             "does Penumbra")
        out.power = 0.0
        return
    if scale[2] > 0.0:
        return
    normal = np.cross(matrix[:3, 0], matrix[:3, 1])       # the light's X/Y plane
    if normal[2] == 0.0:
        # the tweak lies in the plane: the inverse stays singular and Cycles' cone is empty
        warn(f"spot light '{name}' has a zero Z scale and a vertical X/Y plane: Cycles renders no light "
             "from it, and neither does Penumbra")
        out.power = 0.0
        return
    if out.radius <= 0.0:
        # no radius, no importance in Cycles' light tree anywhere (irradiance.cycles_radius_share)
        warn(f"spot light '{name}' has a zero Z scale and no radius: Cycles renders no light from it, and "
             "neither does Penumbra")
        out.power = 0.0
        return
    frame = np.array(matrix, dtype=np.float64)
    frame[:3, 2] = normal * np.sign(normal[2])           # lit half-space: local -Z, below the plane
    out.matrix = orthonormal_frame(frame, 2, 0)
    out.spot_scale = np.array([1.0, 1.0, 0.0])           # the cone: every direction on the lit side
    out.spot_axisless = True
    reach = out.radius * 4096.0
    warn(f"spot light '{name}' has a zero Z scale: as in Cycles, it lights the half-space below its X/Y "
         f"plane, whatever its cone, and only within about {reach:.3g} m of it, where Cycles' light tree "
         "still samples it")


# ----------------------------------------------------------------------------------------------------------
# camera
# ----------------------------------------------------------------------------------------------------------

def light_texture(light, warn) -> np.ndarray | None:
    """The image an area light's Emission colour comes from, as (H, W, 3) linear RGB, or None.

    Recognised: Light Output ← Emission whose Color input is linked (through reroutes) from an Image
    Texture node with an image; the image spans the light's local [-1, 1]² with u along +X and v along +Y
    (Blender's default light UVs). Anything else linked into the colour falls back to the plain light
    colour with a warning."""
    tree = getattr(light, "node_tree", None) if getattr(light, "use_nodes", False) else None
    if tree is None:
        return None
    for node in tree.nodes:
        if node.type != "EMISSION" or not node.inputs["Color"].is_linked:
            continue
        source = _follow_reroutes(node.inputs["Color"])
        src_node = source[0] if source is not None else None
        image = getattr(src_node, "image", None) if src_node is not None and src_node.type == "TEX_IMAGE" else None
        if image is None or image.size[0] == 0 or image.size[1] == 0:
            warn(f"light '{light.name}': emission colour comes from a node setup Penumbra does not read; "
                 "using the light colour")
            return None
        return image_linear_rgb(image, warn)
    return None


# sRGB → linear for the 256 values an 8-bit channel can hold (IEC 61966-2-1's decoding curve).
_SRGB_BYTES = np.arange(256) / 255.0
_SRGB_TO_LINEAR = np.where(_SRGB_BYTES <= 0.04045, _SRGB_BYTES / 12.92,
                           ((_SRGB_BYTES + 0.055) / 1.055) ** 2.4).astype(np.float32)
_LINEAR_SPACES = ("Linear", "Linear Rec.709", "Non-Color", "Raw", "Generic Data")


def image_linear_rgb(image, warn) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of a bpy Image, row 0 at the bottom (as Blender stores it): `image_rgb`
    with sRGB-encoded bytes decoded."""
    rgb, encoded = image_rgb(image, warn)
    return _SRGB_TO_LINEAR[rgb] if encoded else rgb


def image_rgb(image, warn) -> tuple[np.ndarray, bool]:
    """(pixels, srgb_encoded) of a bpy Image, row 0 at the bottom (as Blender stores it).

    Float images are already scene-linear in memory: (H, W, 3) float32, False. 8-bit images hold values in
    their colour space: linear and data spaces come back as float32 as they are (False); sRGB, and with a
    warning any other space, as the (H, W, 3) uint8 bytes themselves (True), to be decoded after filtering
    as Cycles does with 8-bit sRGB images (it interpolates the bytes, then converts; between a light and a
    dark texel the two orders differ by up to 2x)."""
    w, h = image.size
    c = image.channels
    pixels = np.empty(w * h * c, np.float32)
    image.pixels.foreach_get(pixels)
    rgb = pixels.reshape(h, w, c)[..., :3] if c >= 3 else np.repeat(pixels.reshape(h, w, c)[..., :1], 3, -1)
    space = image.colorspace_settings.name
    if not image.is_float and space not in _LINEAR_SPACES and not image.colorspace_settings.is_data:
        if space != "sRGB":
            warn(f"image '{image.name}': colour space '{space}' is decoded as sRGB")
        return np.ascontiguousarray(np.rint(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)), True
    return np.ascontiguousarray(rgb, dtype=np.float32), False


def render_size(scene) -> tuple[int, int]:
    r = scene.render
    return (max(1, int(r.resolution_x * r.resolution_percentage // 100)),
            max(1, int(r.resolution_y * r.resolution_percentage // 100)))


def make_camera(depsgraph, scene, width: int, height: int, warnings: list[str]) -> Camera:
    cam = scene.camera
    if cam is None:
        raise ValueError(f"Scene '{scene.name}' has no camera: add a camera and make it the scene's active "
                         f"camera (Scene properties > Camera)")
    if not cam.is_evaluated:
        cam = cam.evaluated_get(depsgraph)
    r = scene.render
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    world = orthonormal_frame(_matrix_np(cam.matrix_world), 2, 1)
    data = cam.data
    is_ortho = False
    clip_start, clip_end = 0.1, 100.0
    if data is not None and hasattr(data, "clip_start"):
        is_ortho = data.type == "ORTHO"
        clip_start, clip_end = float(data.clip_start), float(data.clip_end)
        if data.type == "PANO":
            warnings.append(f"camera '{cam.name}' is panoramic: rendered with a perspective projection")
    return Camera(name=cam.name, view=np.linalg.inv(world), projection=_matrix_np(proj),
                  width=int(width), height=int(height), is_ortho=is_ortho,
                  clip_start=clip_start, clip_end=clip_end)


# ----------------------------------------------------------------------------------------------------------
# extraction
# ----------------------------------------------------------------------------------------------------------

def _role(ob) -> str:
    props = getattr(ob, "penumbra", None)
    return str(getattr(props, "role", "BOTH")) if props is not None else "BOTH"


def _importance(ob) -> float:
    """Budget importance 0 … 1 (BACKPROJECTION's importance budget map): the custom property
    `penumbra_importance` where the object has one (scripts, linked data), else its Penumbra setting. Read
    from the original object: the depsgraph's evaluated copies answer 0 for both."""
    ob = getattr(ob, "original", None) or ob
    value = ob.get("penumbra_importance") if hasattr(ob, "get") else None
    if value is None:
        props = getattr(ob, "penumbra", None)
        value = getattr(props, "importance", 0.0) if props is not None else 0.0
    try:
        return min(max(float(value), 0.0), 1.0)
    except (TypeError, ValueError):
        raise ValueError(f"Object '{ob.name}': custom property 'penumbra_importance' must be a number "
                         f"0 … 1, got {value!r}") from None


def setting_images(scene, settings=None) -> dict:
    """The images settings name, read here where bpy is: BACKPROJECTION's importance image (bp_budget_image)
    when its budget map is IMPORTANCE, as a Blender image datablock's pixels or a blend-relative file. A
    plain file path the technique reads itself; a name that is neither is an error naming the setting.
    `settings` (RenderSettings, e.g. with the command line's --set) stand in for scene.penumbra."""
    if settings is not None:
        name, mode = settings.option("bp_budget_image"), settings.option("bp_budget_map")
    else:
        props = getattr(scene, "penumbra", None)
        name, mode = getattr(props, "bp_budget_image", ""), getattr(props, "bp_budget_map", "")
    name = str(name or "")
    if not name or mode != "IMPORTANCE":
        return {}
    import bpy
    from ..core import importance
    image = bpy.data.images.get(name)
    if image is not None:
        w, h = image.size
        channels = image.channels
        if w == 0 or h == 0:
            raise ValueError(f"Setting 'bp_budget_image': image '{name}' has no pixels (not loaded or empty)")
        pixels = np.empty(w * h * channels, np.float32)
        image.pixels.foreach_get(pixels)
        return {name: importance.grey(pixels.reshape(h, w, channels))}
    path = bpy.path.abspath(name)
    return {name: importance.load_grey(path, "bp_budget_image")}


def extract(depsgraph, scene=None, *, width: int | None = None, height: int | None = None,
            settings=None) -> SceneSnapshot:
    """Snapshot of everything visible in `depsgraph` (render or viewport). `width`/`height` override the
    camera resolution (otherwise render resolution × percentage); `settings`: the RenderSettings the frame
    will use, for the images they name (else scene.penumbra's)."""
    if scene is None:
        scene = depsgraph.scene
    warnings: list[str] = []
    warned: set[str] = set()

    def warn_once(text: str):
        if text not in warned:
            warned.add(text)
            warnings.append(text)

    objects: list[ObjectInfo] = []
    object_index: dict[tuple, int] = {}
    albedo_tables: list[tuple] = []          # per distinct slot list: one AlbedoSource per material slot
    layers_read: set[tuple] = set()          # (mesh pointer, table id) whose UV / colour layers are read
    material_cache: dict[int, AlbedoSource] = {}
    table_cache: dict[tuple, int] = {}
    # Per-instance lookup: (object name, instancer name, mesh pointer) -> (object id, albedo table id).
    # Instances are temporary Object copies whose pointers get reused, so names identify them.
    inst_cache: dict[tuple, tuple[int, int]] = {}
    mesh_arrays: dict[int, _MeshArrays | None] = {}
    groups: dict[int, tuple[list, list, list]] = {}  # mesh pointer -> (world matrices, object ids, table ids)
    lights: list[Light] = []

    # Hot loop: ~100k iterations for instance-heavy scenes, so only cheap RNA reads per instance.
    for inst in depsgraph.object_instances:
        ob = inst.object
        ob_type = ob.type
        if ob_type == "MESH":
            if inst.is_instance:
                parent = inst.parent
                parent_name = parent.name
            else:
                if not inst.show_self:   # e.g. a particle emitter with "Show Emitter" off
                    continue
                parent, parent_name = None, ""
            mesh = ob.data
            mesh_ptr = mesh.as_pointer()
            key = (ob.name, parent_name, mesh_ptr)
            ids = inst_cache.get(key)
            if ids is None:
                ids = inst_cache[key] = _instance_ids(ob, parent, mesh, objects, object_index, albedo_tables,
                                                      material_cache, table_cache, warn_once)
            group = groups.get(mesh_ptr)
            if group is None:
                if mesh_ptr not in mesh_arrays:
                    mesh_arrays[mesh_ptr] = read_mesh(mesh)
                group = groups[mesh_ptr] = ([], [], [])
            if (mesh_ptr, ids[1]) not in layers_read:
                layers_read.add((mesh_ptr, ids[1]))
                sources = albedo_tables[ids[1]]
                if mesh_arrays[mesh_ptr] is not None and any(src.varies for src in sources):
                    read_corner_layers(mesh_arrays[mesh_ptr], mesh, sources, ob.name, warn_once)
            group[0].append(inst.matrix_world.copy())   # must copy: the iterator reuses the matrix
            group[1].append(ids[0])
            group[2].append(ids[1])
        elif ob_type == "LIGHT":
            lights.append(make_light(ob.name, ob.data, _matrix_np(inst.matrix_world), warn_once))
            linking = getattr(ob, "light_linking", None)        # Blender 4.0+
            if linking is not None and (linking.receiver_collection or linking.blocker_collection):
                warn_once(f"light '{ob.name}' uses light or shadow linking, which Penumbra does not model: every "
                          f"object receives its light and blocks it")

    geometry, textures = _assemble(groups, mesh_arrays, albedo_tables, warn_once)
    geometry = sanitize(geometry, objects, warnings)

    if width is None or height is None:
        w, h = render_size(scene)
        width = w if width is None else width
        height = h if height is None else height
    camera = make_camera(depsgraph, scene, int(width), int(height), warnings)

    # A scene without lights is not an error here; the pipeline warns (once) when it renders it.
    return SceneSnapshot(objects=objects, lights=lights, camera=camera, name=scene.name, warnings=warnings,
                         textures=textures, images=setting_images(scene, settings), **geometry)


def object_info(ob, parent) -> tuple[str, bool, bool, str, float, float]:
    """(name, caster, receiver, role, importance, terminator offset) of a mesh object as one instance sees it
    (ObjectInfo's fields, in order), `parent` its instancer (None when not instanced): what the final render
    and the viewport both read. Cycles ANDs the instancer's ray visibility into the instance's; an instance
    whose own Shadow Role is Both takes its instancer's, one without importance its instancer's."""
    caster = bool(ob.visible_shadow)
    receiver = bool(ob.visible_camera)
    role = _role(ob)
    importance = _importance(ob)
    if parent is not None and parent != ob:
        caster = caster and bool(parent.visible_shadow)
        receiver = receiver and bool(parent.visible_camera)
        if role == "BOTH":
            role = _role(parent)
        if importance == 0.0:
            importance = _importance(parent)
    return ob.name, caster, receiver, role, importance, float(getattr(ob, "shadow_terminator_geometry_offset", 0.1))


def _instance_ids(ob, parent, mesh, objects, object_index, albedo_tables, material_cache, table_cache,
                  warn_once) -> tuple[int, int]:
    okey = object_info(ob, parent)
    oid = object_index.get(okey)
    if oid is None:
        oid = object_index[okey] = len(objects)
        objects.append(ObjectInfo(*okey, closed=mesh_is_closed(mesh)))

    mats = [slot.material for slot in ob.material_slots]
    if not mats:
        mats = list(mesh.materials)
    sources = []
    for mat in mats:
        mkey = mat.as_pointer() if mat is not None else 0
        src = material_cache.get(mkey)
        if src is None:
            src = material_cache[mkey] = material_albedo_source(mat, warn_once)
        sources.append(src)
    tkey = tuple(sources) or (CONSTANT_GREY,)
    tid = table_cache.get(tkey)
    if tid is None:
        tid = table_cache[tkey] = len(albedo_tables)
        albedo_tables.append(tkey)
    return oid, tid


class AlbedoTextures:
    """The snapshot's albedo textures: one per (image, interpolation, extension), each image read once."""

    def __init__(self, warn):
        self.textures: list[AlbedoTexture] = []
        self._index: dict[tuple, int] = {}
        self._pixels: dict[int, tuple] = {}
        self._warn = warn

    def index(self, src: AlbedoSource) -> int:
        key = (src.image_key, src.interpolation, src.extension)
        i = self._index.get(key)
        if i is None:
            pixels = self._pixels.get(src.image_key)
            if pixels is None:
                pixels = self._pixels[src.image_key] = image_rgb(src.image, self._warn)
            i = self._index[key] = len(self.textures)
            self.textures.append(AlbedoTexture(src.image.name, pixels[0], src.interpolation, src.extension,
                                               srgb=pixels[1]))
        return i


def table_arrays(arrays: _MeshArrays, sources: tuple, textures: AlbedoTextures):
    """One mesh under one slot list: per-triangle albedo (t, 3) and, when a source varies over the surface,
    (texture id (t,), uv (t, 3, 2), corner colour (t, 3, 3)); else None."""
    mat = np.clip(arrays.mat, 0, len(sources) - 1)
    albedo = np.array([src.color for src in sources], np.float32)[mat]
    if not any(src.varies for src in sources):
        return albedo, None
    t = mat.shape[0]
    tex = np.full(t, -1, np.int32)
    uv = np.zeros((t, 3, 2), np.float32)
    col = np.ones((t, 3, 3), np.float32)
    for i, src in enumerate(sources):
        sel = mat == i
        if not src.varies or not sel.any():
            continue
        if src.image_key:
            tex[sel] = textures.index(src)
            coords = arrays.uv[src.uv_map][sel]
            if src.uv_matrix is not None:
                m = np.asarray(src.uv_matrix, np.float32)
                coords = coords @ m[:, :2].T + m[:, 2]
            uv[sel] = coords
        if src.attribute is not None:
            col[sel] = arrays.colors[src.attribute][sel]
    return albedo, (tex, uv, col)


def _assemble(groups, mesh_arrays, albedo_tables, warn) -> tuple[dict, list]:
    """The geometry arrays of every mesh group (and the textures they sample)."""
    textures = AlbedoTextures(warn)
    pos_parts, nrm_parts, oid_parts, alb_parts, var_parts = [], [], [], [], []
    for mesh_ptr, (mats, oids, tids) in groups.items():
        arrays = mesh_arrays[mesh_ptr]
        if arrays is None:
            continue
        t = arrays.pos.shape[0]
        pos, nrm, flipped = transform_instances(arrays, _stack_matrices(mats))
        pos_parts.append(pos)
        nrm_parts.append(nrm)
        oid_parts.append(np.repeat(np.asarray(oids, np.int32), t))
        tids = np.asarray(tids, np.int32)
        k = len(tids)
        per_table = {int(tid): table_arrays(arrays, albedo_tables[tid], textures) for tid in np.unique(tids)}
        if len(per_table) == 1:
            alb = np.broadcast_to(next(iter(per_table.values()))[0], (k, t, 3))
        else:
            alb = np.empty((k, t, 3), np.float32)
            for tid, (table_albedo, _) in per_table.items():
                alb[tids == tid] = table_albedo
        alb_parts.append(alb.reshape(-1, 3))
        if all(var is None for _, var in per_table.values()):
            var_parts.append(None)
            continue
        tex = np.full((k, t), -1, np.int32)
        uv = np.zeros((k, t, 3, 2), np.float32)
        col = np.ones((k, t, 3, 3), np.float32)
        for tid, (_, var) in per_table.items():
            if var is not None:
                rows = tids == tid
                tex[rows], uv[rows], col[rows] = var
        if flipped.any():       # _flip swapped corners 1 and 2 of mirrored instances: so must their data be
            uv[flipped] = uv[flipped][:, :, [0, 2, 1]]
            col[flipped] = col[flipped][:, :, [0, 2, 1]]
        var_parts.append((tex.reshape(-1), uv.reshape(-1, 3, 2), col.reshape(-1, 3, 3)))
    if not pos_parts:
        return SceneSnapshot.empty_geometry(), []
    if len(pos_parts) == 1:
        geometry = dict(positions=pos_parts[0], normals=nrm_parts[0], object_id=oid_parts[0],
                        albedo=np.ascontiguousarray(alb_parts[0]))
    else:
        geometry = dict(positions=np.concatenate(pos_parts), normals=np.concatenate(nrm_parts),
                        object_id=np.concatenate(oid_parts), albedo=np.concatenate(alb_parts))
    if any(v is not None for v in var_parts):
        def part(i, v, n):
            if v is not None:
                return v[i]
            return (np.full(n, -1, np.int32), np.zeros((n, 3, 2), np.float32), np.ones((n, 3, 3), np.float32))[i]
        counts = [p.shape[0] for p in pos_parts]
        tex, uv, col = (np.concatenate([part(i, v, n) for v, n in zip(var_parts, counts)]) for i in range(3))
        if (tex >= 0).any():
            geometry.update(texture_id=tex, uv=uv)
        if not (col == 1.0).all():
            geometry.update(corner_color=col)
    return geometry, textures.textures


def sanitize(geometry: dict, objects: list[ObjectInfo], warnings: list[str]) -> dict:
    """Drop non-finite and zero-area triangles (one warning per object and cause), repair unusable normals.

    Zero area means below REL_AREA_EPS × (scene bounding-box diagonal)², so millimetre-scale scenes keep
    their small triangles while exact duplicates / collinear corners are removed."""
    pos = geometry["positions"]
    n = pos.shape[0]
    if n == 0:
        return geometry
    if np.isfinite(pos).all():
        finite = None
        fpos = pos
    else:
        finite = np.isfinite(pos.reshape(n, 9)).all(axis=1)
        fpos = pos[finite]
    if fpos.shape[0]:
        flat = fpos.reshape(-1, 3)
        diag2 = sum((float(flat[:, i].max()) - float(flat[:, i].min())) ** 2 for i in range(3))
    else:
        diag2 = 0.0
    q = pos.transpose(1, 2, 0)            # (corner, xyz, triangle) view
    e1 = q[1] - q[0]
    e2 = q[2] - q[0]
    cross = np.stack([e1[1] * e2[2] - e1[2] * e2[1],
                      e1[2] * e2[0] - e1[0] * e2[2],
                      e1[0] * e2[1] - e1[1] * e2[0]])          # (3, n) = 2 × area × unit normal
    area2 = cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]   # (2 area)²
    with np.errstate(invalid="ignore"):
        tiny = ~(area2 > 4.0 * (REL_AREA_EPS * diag2) ** 2)
    if finite is not None:
        tiny &= finite
    n_obj = len(objects)
    oid = geometry["object_id"]
    if finite is not None:
        counts = np.bincount(oid[~finite], minlength=n_obj)
        for i in np.flatnonzero(counts):
            warnings.append(f"object '{objects[i].name}': dropped {counts[i]} triangle(s) with NaN/Inf vertices")
    any_tiny = bool(tiny.any())
    if any_tiny:
        counts = np.bincount(oid[tiny], minlength=n_obj)
        for i in np.flatnonzero(counts):
            warnings.append(f"object '{objects[i].name}': dropped {counts[i]} zero-area triangle(s)")
    if finite is not None or any_tiny:
        keep = ~tiny if finite is None else (finite & ~tiny)
        geometry = {k: v[keep] for k, v in geometry.items()}
        cross = cross[:, keep]
        area2 = area2[keep]
    # Normals that cannot be used (NaN or zero, e.g. from a degenerate source face) -> geometric normal.
    nrm = geometry["normals"]
    nlen2 = np.einsum("tci,tci->tc", nrm, nrm)
    bad = ~(nlen2 > 1e-12)
    if bad.any():
        rows, cols = np.nonzero(bad)
        face = (cross[:, rows] / np.sqrt(area2[rows])).T.astype(np.float32)
        nrm[rows, cols] = face
    return geometry
