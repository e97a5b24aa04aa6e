"""engine/blender/extract.py: Blender depsgraph -> SceneSnapshot. Scenes are built in code on an empty factory scene."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from mathutils import Vector  # noqa: E402  (bpy must load first)

from penumbra.engine.blender import extract as scene_mod  # noqa: E402
from penumbra.engine.core.snapshot import AREA, DISK, ELLIPSE, POINT, RECTANGLE, SPOT, SQUARE, SUN  # noqa: E402


# ----------------------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------------------

@pytest.fixture
def scn():
    """Fresh empty scene with a camera at +Z looking down and one point light."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 320, 240, 100
    add_camera(sc, location=(0, 0, 10))
    light = bpy.data.lights.new("Key", "POINT")
    lob = bpy.data.objects.new("Key", light)
    lob.location = (0, 0, 5)
    sc.collection.objects.link(lob)
    return sc


def add_camera(sc, location=(0, 0, 10), rotation=(0, 0, 0), name="Cam"):
    cam = bpy.data.cameras.new(name)
    ob = bpy.data.objects.new(name, cam)
    ob.location, ob.rotation_euler = location, rotation
    sc.collection.objects.link(ob)
    sc.camera = ob
    return ob


CUBE_VERTS = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
CUBE_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def add_mesh(sc, name, verts, faces, collection=None, **transform):
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], faces)
    me.validate()
    ob = bpy.data.objects.new(name, me)
    for key, value in transform.items():
        setattr(ob, key, value)
    (collection or sc.collection).objects.link(ob)
    return ob


def add_cube(sc, name="Cube", **transform):
    ob = add_mesh(sc, name, CUBE_VERTS, CUBE_FACES, **transform)
    # from_pydata winding above is not guaranteed outward; make it so.
    import bmesh
    bm = bmesh.new()
    bm.from_mesh(ob.data)
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(ob.data)
    bm.free()
    return ob


def snap(**kw):
    dg = bpy.context.evaluated_depsgraph_get()
    return scene_mod.extract(dg, **kw)


def face_normals(pos):
    n = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def assert_outward(s, center):
    """Winding is counter-clockwise seen from the front and the shading normals point away from center."""
    geo = face_normals(s.positions.astype(np.float64))
    centroid = s.positions.mean(axis=1)
    assert (np.einsum("ij,ij->i", geo, centroid - center) > 0).all(), "winding not CCW from outside"
    for c in range(3):
        assert (np.einsum("ij,ij->i", s.normals[:, c], centroid - center) > 0).all(), "normals point inward"


# ----------------------------------------------------------------------------------------------------------
# geometry
# ----------------------------------------------------------------------------------------------------------

def test_transformed_cube_world_corners(scn):
    ob = add_cube(scn, location=(1.0, 2.0, 3.0), rotation_euler=(0.3, -0.2, 0.7), scale=(1.0, 2.0, 0.5))
    s = snap()
    assert s.triangle_count == 12
    assert s.positions.dtype == np.float32 and s.normals.dtype == np.float32
    assert s.object_id.dtype == np.int32 and s.albedo.dtype == np.float32
    mw = ob.matrix_world
    expected = np.array([tuple(mw @ Vector(v)) for v in CUBE_VERTS])
    corners = s.positions.reshape(-1, 3)
    # Every corner is a transformed cube vertex, and every transformed vertex is used.
    d = np.linalg.norm(corners[:, None, :] - expected[None, :, :], axis=2)
    assert d.min(axis=1).max() < 1e-5
    assert d.min(axis=0).max() < 1e-5
    assert_outward(s, np.array([1.0, 2.0, 3.0]))
    # Flat shading: corner normals equal the geometric normal even under non-uniform scale.
    geo = face_normals(s.positions.astype(np.float64))
    for c in range(3):
        assert np.allclose(s.normals[:, c], geo, atol=1e-5)
    assert s.objects[0].name == "Cube" and (s.object_id == 0).all()
    assert np.allclose(s.albedo, 0.8)


def test_smooth_shading_normals(scn):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=1.0, location=(0, 0, 0))
    bpy.ops.object.shade_smooth()
    s = snap()
    # Smooth: corner normals are Blender's (continuous across faces), not the face normals.
    dg = bpy.context.evaluated_depsgraph_get()
    me = bpy.context.active_object.evaluated_get(dg).data
    expected = np.array([tuple(me.corner_normals[i].vector) for t in me.loop_triangles for i in t.loops])
    assert np.allclose(s.normals.reshape(-1, 3), expected, atol=1e-6)
    corners = s.positions.reshape(-1, 3)
    radial = corners / np.linalg.norm(corners, axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", s.normals.reshape(-1, 3), radial) > 0.97).all()
    assert not np.allclose(s.normals[:, 0], face_normals(s.positions.astype(np.float64)), atol=1e-2)
    bpy.ops.object.shade_flat()
    s = snap()
    geo = face_normals(s.positions.astype(np.float64))
    assert np.allclose(s.normals[:, 0], geo, atol=1e-4)


def test_flat_faces_shade_with_their_triangles_normals(scn):
    """Cycles shades a flat (sharp) face's triangles with each triangle's own geometric normal, not the face
    normal Blender's corner normals carry; on a non-planar quad the two differ, and near the terminator
    they disagree on whether the light is above the surface at all (fuzz seed 3013: a flat monkey's faces
    came out unlit where Cycles lit and shadowed them). Smooth faces keep their corner normals, in a mesh
    that mixes both, also mirrored and instanced."""
    verts = [(0, 0, 0), (1, 0, 0.4), (1, 1, 0), (0, 1, 0.3), (2, 0, 0), (2, 1, 0.5)]
    ob = add_mesh(scn, "Bent", verts, [(0, 1, 2, 3), (1, 4, 5, 2)], scale=(1, -1, 1))
    me = ob.data
    me.polygons[0].use_smooth = False           # sharp: its two triangles' own normals
    me.polygons[1].use_smooth = True            # smooth: corner normals
    me.update()
    s = snap()
    geo = face_normals(s.positions.astype(np.float64))
    dg = bpy.context.evaluated_depsgraph_get()
    ev = ob.evaluated_get(dg).data
    flat_tris = np.array([t.polygon_index == 0 for t in ev.loop_triangles])
    assert flat_tris.sum() == 2 and not np.allclose(geo[0], geo[1], atol=1e-2)    # the quad is bent
    for c in range(3):
        assert np.allclose(s.normals[flat_tris, c], geo[flat_tris], atol=1e-5)
    assert not np.allclose(s.normals[~flat_tris, 0], geo[~flat_tris], atol=1e-2)
    # every edge sharp and no sharp_face attribute: the normals domain is FACE, every triangle flat
    bpy.data.objects.remove(ob)
    ob = add_mesh(scn, "AllSharp", verts, [(0, 1, 2, 3), (1, 4, 5, 2)])
    ob.data.shade_smooth()
    for e in ob.data.edges:
        e.use_edge_sharp = True
    ob.data.update()
    assert ob.data.normals_domain == "FACE"
    s = snap()
    geo = face_normals(s.positions.astype(np.float64))
    for c in range(3):
        assert np.allclose(s.normals[:, c], geo, atol=1e-5)


def test_flattened_object_normals_come_from_its_triangles(scn):
    """A scale axis at 0 (issue 10 item 4): the cofactor sends each smooth normal to ±(that axis) by the sign
    of its component along it, so neighbouring corners disagree. The normals are the flattened triangles'
    own, unit length, also for an instance (batched path). Cycles' shadow of such an object:
    tests/test_fuzz.py::test_flattened_caster_shadows_as_in_cycles."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=1.0, location=(0, 0, 1))
    bpy.ops.object.shade_smooth()
    ob = bpy.context.active_object
    ob.rotation_euler, ob.scale = (0.4, 0.2, 0.0), (0.8, 0.0, 0.8)
    src_col = bpy.data.collections.new("Src")
    src_col.objects.link(add_mesh(scn, "Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 1)], [(0, 1, 2)],
                                  collection=None))
    for i, loc in enumerate([(5, 0, 0), (0, 7, 1)]):
        e = bpy.data.objects.new(f"Inst{i}", None)
        e.instance_type, e.instance_collection, e.location, e.scale = "COLLECTION", src_col, loc, (1, 1, 0)
        scn.collection.objects.link(e)
    s = snap()
    assert s.triangle_count > 0
    geo = face_normals(s.positions.astype(np.float64))
    for c in range(3):
        assert np.allclose(s.normals[:, c], geo, atol=1e-5)
    assert np.allclose(np.linalg.norm(s.normals, axis=-1), 1.0, atol=1e-5)


def test_collection_instances(scn):
    src_col = bpy.data.collections.new("Src")
    add_mesh(scn, "Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], collection=src_col)
    for i, loc in enumerate([(5, 0, 0), (0, 7, 1)]):
        e = bpy.data.objects.new(f"Inst{i}", None)
        e.instance_type, e.instance_collection, e.location = "COLLECTION", src_col, loc
        scn.collection.objects.link(e)
    s = snap()
    assert s.triangle_count == 2
    got = sorted(map(tuple, np.round(s.positions[:, 0], 5)))
    assert got == [(0.0, 7.0, 1.0), (5.0, 0.0, 0.0)]
    assert all(o.name == "Tri" for o in s.objects)


def test_instancer_visibility_is_anded(scn):
    src_col = bpy.data.collections.new("Src")
    add_mesh(scn, "Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], collection=src_col)
    for i in range(2):
        e = bpy.data.objects.new(f"Inst{i}", None)
        e.instance_type, e.instance_collection, e.location = "COLLECTION", src_col, (3 * i, 0, 0)
        e.visible_shadow = i == 0
        scn.collection.objects.link(e)
    s = snap()
    casters = s.caster_mask()
    assert casters.sum() == 1
    assert np.isclose(s.positions[casters][0, 0, 0], 0.0)
    assert s.receiver_mask().all()


def _gn_instance_on_points():
    ng = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    ng.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    gin, gout = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    iop = ng.nodes.new("GeometryNodeInstanceOnPoints")
    cube = ng.nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (0.5, 0.5, 0.5)
    ng.links.new(gin.outputs[0], iop.inputs["Points"])
    ng.links.new(cube.outputs[0], iop.inputs["Instance"])
    ng.links.new(iop.outputs[0], gout.inputs[0])
    return ng


def test_geometry_nodes_instances(scn):
    points = [(0, 0, 0), (3, 0, 0), (0, 4, 2)]
    host = add_mesh(scn, "Host", points, [], location=(1, 1, 1))
    host.modifiers.new("gn", "NODES").node_group = _gn_instance_on_points()
    s = snap()
    assert s.triangle_count == 3 * 12
    centers = sorted(map(tuple, np.round(s.positions.reshape(-1, 12 * 3, 3).mean(axis=1), 4)))
    assert centers == sorted((x + 1.0, y + 1.0, z + 1.0) for x, y, z in points)
    for c in centers:
        sel = np.all(np.isclose(s.positions.reshape(-1, 36, 3).mean(axis=1), c, atol=1e-4), axis=1)
        sub = scene_mod.SceneSnapshot(s.positions.reshape(-1, 12, 3, 3)[sel][0],
                                      s.normals.reshape(-1, 12, 3, 3)[sel][0], s.object_id[:12],
                                      s.albedo[:12], s.objects, [], s.camera)
        assert_outward(sub, np.array(c))


def test_vertex_instancer_follows_show_instancer(scn):
    parent = add_mesh(scn, "Parent", [(10, 0, 0), (10, 3, 0), (10, 0, 3)], [(0, 1, 2)])
    child = add_mesh(scn, "Child", [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], [(0, 1, 2)])
    child.parent = parent
    parent.instance_type = "VERTS"
    s = snap()
    n_parent = int((s.object_id == [o.name for o in s.objects].index("Parent")).sum())
    assert n_parent == 1
    parent.show_instancer_for_viewport = False
    s = snap()
    assert "Parent" not in {o.name for o in s.objects}
    # Three vertex instances (plus, in a viewport depsgraph, the child itself).
    assert s.triangle_count >= 3


def test_negative_scale_keeps_winding_and_outward_normals(scn):
    add_cube(scn, location=(2, 0, 0), scale=(-1.0, 1.5, 1.0))
    s = snap()
    assert s.triangle_count == 12
    assert_outward(s, np.array([2.0, 0.0, 0.0]))
    # Mirrored twice (det > 0 again) is an ordinary rotation.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    add_camera(sc)
    add_cube(sc, scale=(-1.0, -1.0, 2.0))
    s = snap()
    assert_outward(s, np.zeros(3))


def test_negative_scale_instances_mixed(scn):
    """Batched path: several instances of one mesh, some mirrored."""
    src_col = bpy.data.collections.new("Src")
    add_cube(scn, "C", collection=None)
    cube = bpy.data.objects["C"]
    scn.collection.objects.unlink(cube)
    src_col.objects.link(cube)
    centers = []
    for i, sc_ in enumerate([(1, 1, 1), (-1, 1, 1), (1, -2, 1), (-1, -1, -1)]):
        e = bpy.data.objects.new(f"I{i}", None)
        e.instance_type, e.instance_collection = "COLLECTION", src_col
        e.location, e.scale = (5 * i, 0, 0), sc_
        scn.collection.objects.link(e)
        centers.append((5 * i, 0, 0))
    s = snap()
    assert s.triangle_count == 48
    for c in centers:
        sel = np.isclose(s.positions.mean(axis=1)[:, 0], c[0], atol=2.1)
        assert sel.sum() == 12
        sub = scene_mod.SceneSnapshot(s.positions[sel], s.normals[sel], s.object_id[sel], s.albedo[sel],
                                      s.objects, [], s.camera)
        assert_outward(sub, np.array(c, dtype=float))


def test_modifiers_are_applied(scn):
    ob = add_cube(scn)
    assert snap().triangle_count == 12
    sub = ob.modifiers.new("sub", "SUBSURF")
    sub.levels = sub.render_levels = 2
    assert snap().triangle_count == 12 * 16
    ob.modifiers.remove(sub)
    arr = ob.modifiers.new("arr", "ARRAY")
    arr.count = 3
    arr.relative_offset_displace = (1.5, 0, 0)
    s = snap()
    assert s.triangle_count == 36
    lo, hi = s.bounds()
    assert np.allclose(lo, [-1, -1, -1], atol=1e-5)
    assert np.allclose(hi, [1 + 2 * 3.0, 1, 1], atol=1e-5)


def test_curve_and_text_objects_become_triangles(scn):
    cu = bpy.data.curves.new("Tube", "CURVE")
    cu.dimensions, cu.bevel_depth = "3D", 0.1
    spline = cu.splines.new("POLY")
    spline.points.add(1)
    spline.points[1].co = (2, 0, 0, 1)
    scn.collection.objects.link(bpy.data.objects.new("Tube", cu))
    txt = bpy.data.curves.new("Label", "FONT")
    txt.body = "Hi"
    scn.collection.objects.link(bpy.data.objects.new("Label", txt))
    s = snap()
    names = {s.objects[i].name for i in np.unique(s.object_id)}
    assert names == {"Tube", "Label"}
    # Converted once each (Blender lists both the curve object and its evaluated mesh instance).
    tube_tris = int((s.object_id == [o.name for o in s.objects].index("Tube")).sum())
    tube_mesh = bpy.data.objects["Tube"].evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
    assert tube_tris == len(tube_mesh.loop_triangles)


def test_empty_mesh_and_hidden_objects(scn):
    add_mesh(scn, "Empty", [], [])
    hidden = add_cube(scn, "Hidden")
    hidden.hide_viewport = True
    s = snap()
    assert s.triangle_count == 0
    assert s.positions.shape == (0, 3, 3) and s.albedo.shape == (0, 3)
    assert not any("Empty" in w for w in s.warnings)


def test_visibility_flags_and_role(scn):
    a = add_cube(scn, "A")
    b = add_cube(scn, "B", location=(3, 0, 0))
    a.visible_shadow = False
    b.visible_camera = False
    s = snap()
    info = {o.name: o for o in s.objects}
    assert info["A"].caster is False and info["A"].receiver is True
    assert info["B"].caster is True and info["B"].receiver is False
    assert info["A"].role == "BOTH"
    assert s.caster_mask().sum() == 12 and s.receiver_mask().sum() == 12


# ----------------------------------------------------------------------------------------------------------
# materials
# ----------------------------------------------------------------------------------------------------------

def _principled(name, rgb):
    mat = bpy.data.materials.new(name)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    return mat


def test_material_albedo_per_slot(scn):
    ob = add_cube(scn)
    red, green = _principled("Red", (0.9, 0.1, 0.05)), _principled("Green", (0.1, 0.7, 0.2))
    ob.data.materials.append(red)
    ob.data.materials.append(green)
    mi = np.zeros(6, np.int32)
    mi[3:] = 1
    ob.data.polygons.foreach_set("material_index", mi)
    ob.data.update()
    s = snap()
    cols = {tuple(np.round(c.astype(np.float64), 4).tolist()) for c in s.albedo}
    assert cols == {(0.9, 0.1, 0.05), (0.1, 0.7, 0.2)}
    assert (np.isclose(s.albedo[:, 0], 0.9)).sum() == 6


def test_material_diffuse_texture_and_none(scn):
    diffuse = bpy.data.materials.new("Diff")
    tree = diffuse.node_tree
    for n in list(tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(n)
    d = tree.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.links.new(d.outputs[0], out.inputs["Surface"])

    tex = _principled("Tex", (0.1, 0.1, 0.1))
    img = tex.node_tree.nodes.new("ShaderNodeTexChecker")
    bsdf = next(n for n in tex.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex.node_tree.links.new(img.outputs["Color"], bsdf.inputs["Base Color"])

    a, b, c, e = (add_cube(scn, n, location=(3 * i, 0, 0)) for i, n in enumerate("ABCE"))
    a.data.materials.append(diffuse)
    b.data.materials.append(tex)
    c.data.materials.append(tex)          # same textured material twice: warned once
    s = snap()
    names = [o.name for o in s.objects]
    alb = {n: s.albedo[s.object_id == names.index(n)] for n in "ABCE"}
    assert np.allclose(alb["A"], [0.2, 0.3, 0.4])
    assert np.allclose(alb["B"], 0.8) and np.allclose(alb["C"], 0.8) and np.allclose(alb["E"], 0.8)
    tex_warnings = [w for w in s.warnings if "'Tex'" in w]
    assert len(tex_warnings) == 1 and "0.8 grey" in tex_warnings[0]


# ----------------------------------------------------------------------------------------------------------
# bad input
# ----------------------------------------------------------------------------------------------------------

def test_nan_and_zero_area_triangles_dropped(scn):
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0),                  # good
             (2, 0, 0), (3, 0, 0), (float("nan"), 1, 0),       # NaN corner
             (4, 0, 0), (5, 0, 0), (6, 0, 0),                  # collinear: zero area
             (7, 0, 0), (7, 0, 0), (7, 1, 0)]                  # repeated corner: zero area
    ob = add_mesh(scn, "Bad", [], [])
    me = ob.data
    me.vertices.add(len(verts))
    me.vertices.foreach_set("co", np.array(verts, np.float32).ravel())
    me.loops.add(12)
    me.loops.foreach_set("vertex_index", np.arange(12, dtype=np.int32))
    me.polygons.add(4)
    me.polygons.foreach_set("loop_start", np.arange(0, 12, 3, dtype=np.int32))
    me.update()
    s = snap()
    assert s.triangle_count == 1
    assert np.allclose(s.positions[0], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert np.isfinite(s.normals).all()
    assert "object 'Bad': dropped 1 triangle(s) with NaN/Inf vertices" in s.warnings
    assert "object 'Bad': dropped 2 zero-area triangle(s)" in s.warnings


def test_millimetre_scene_keeps_small_triangles(scn):
    """The zero-area threshold is relative to the scene size, so a 1e-3-scaled scene loses nothing."""
    ob = add_cube(scn, scale=(1e-3, 1e-3, 1e-3))
    sub = ob.modifiers.new("sub", "SUBSURF")
    sub.levels = 3
    s = snap()
    assert s.triangle_count == 12 * 64
    assert not any("zero-area" in w for w in s.warnings)
    # ...and a sliver that is tiny relative to that scene is still dropped.
    add_mesh(scn, "Sliver", [(0, 0, 0), (1e-3, 0, 0), (5e-4, 1e-19, 0)], [(0, 1, 2)])
    s = snap()
    assert "object 'Sliver': dropped 1 zero-area triangle(s)" in s.warnings


# ----------------------------------------------------------------------------------------------------------
# lights
# ----------------------------------------------------------------------------------------------------------

def _light(sc, name, kind, location=(0, 0, 3), rotation=(0, 0, 0), scale=(1, 1, 1), **props):
    data = bpy.data.lights.new(name, kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(name, data)
    ob.location, ob.rotation_euler, ob.scale = location, rotation, scale
    sc.collection.objects.link(ob)
    return ob


def test_light_types_and_fields(scn):
    bpy.data.objects.remove(bpy.data.objects["Key"])
    _light(scn, "Sq", "AREA", scale=(2, 3, 1), shape="SQUARE", size=0.5, energy=100)
    _light(scn, "Rect", "AREA", scale=(1, -2, 1), shape="RECTANGLE", size=0.5, size_y=0.25, energy=50)
    _light(scn, "Disk", "AREA", shape="DISK", size=0.4, energy=10)
    _light(scn, "Ell", "AREA", shape="ELLIPSE", size=0.4, size_y=0.2, energy=10)
    _light(scn, "Pt", "POINT", location=(1, 2, 3), scale=(5, 5, 5), shadow_soft_size=0.3, energy=1000,
           exposure=1.0, color=(1.0, 0.5, 0.25))
    _light(scn, "Sp", "SPOT", rotation=(0.5, 0, 0), scale=(1, 2, 1), shadow_soft_size=0.1, spot_size=0.8,
           spot_blend=0.3, energy=200, use_shadow=False)
    _light(scn, "Sun", "SUN", rotation=(0.4, 0.2, 0), angle=0.05, energy=3.0)
    s = snap()
    L = {l.name: l for l in s.lights}
    assert set(L) == {"Sq", "Rect", "Disk", "Ell", "Pt", "Sp", "Sun"}
    assert L["Sq"].kind == AREA and L["Sq"].shape == SQUARE
    assert np.isclose(L["Sq"].size_x, 1.0) and np.isclose(L["Sq"].size_y, 1.5)
    assert L["Rect"].shape == RECTANGLE and np.isclose(L["Rect"].size_x, 0.5) and np.isclose(L["Rect"].size_y, 0.5)
    assert L["Disk"].shape == DISK and np.isclose(L["Disk"].size_y, 0.4)
    assert L["Ell"].shape == ELLIPSE and np.isclose(L["Ell"].size_y, 0.2)
    assert np.isclose(L["Ell"].area, math.pi / 4 * 0.4 * 0.2)
    assert L["Pt"].kind == POINT and np.isclose(L["Pt"].radius, 0.3)   # Cycles: radius not scaled
    assert np.isclose(L["Pt"].power, 2000.0) and np.allclose(L["Pt"].color, [1.0, 0.5, 0.25])
    assert np.allclose(L["Pt"].position, [1, 2, 3])
    assert L["Sp"].kind == SPOT and np.isclose(L["Sp"].spot_size, 0.8) and np.isclose(L["Sp"].spot_blend, 0.3)
    assert np.allclose(L["Sp"].spot_scale, [1, 2, 1]) and L["Sp"].casts_shadow is False
    assert L["Sq"].casts_shadow is True
    assert L["Sun"].kind == SUN and np.isclose(L["Sun"].angle, 0.05) and np.isclose(L["Sun"].power, 3.0)
    for light in s.lights:
        m = light.matrix
        assert np.allclose(m[:3, :3].T @ m[:3, :3], np.eye(3), atol=1e-6)
        assert np.isclose(np.linalg.det(m[:3, :3]), 1.0)
    # Emission axis follows the rotation: spot rotated about X by 0.5 rad points along R @ (0, 0, -1).
    rx = np.array([[1, 0, 0], [0, math.cos(0.5), -math.sin(0.5)], [0, math.sin(0.5), math.cos(0.5)]])
    assert np.allclose(L["Sp"].direction, rx @ [0, 0, -1], atol=1e-6)
    # Mirrored light (scale y < 0): still right-handed, emission direction unchanged.
    assert np.allclose(L["Rect"].direction, [0, 0, -1], atol=1e-6)
    assert not any("no lights" in w for w in s.warnings)


def test_light_temperature_normalize_and_zero_size(scn):
    bpy.data.objects.remove(bpy.data.objects["Key"])
    warm = _light(scn, "Warm", "POINT", energy=10, color=(1.0, 1.0, 1.0))
    warm.data.use_temperature = True
    warm.data.temperature = 2700.0
    _light(scn, "Raw", "AREA", size=2.0, energy=5.0)
    bpy.data.objects["Raw"].data.normalize = False
    _light(scn, "Zero", "AREA", size=0.0, energy=5.0)
    s = snap()
    L = {l.name: l for l in s.lights}
    expected = np.array(warm.data.temperature_color[:3])
    assert np.allclose(L["Warm"].color, expected)
    assert L["Warm"].color[0] > L["Warm"].color[2]          # warm white is reddish
    assert np.isclose(L["Raw"].power, 5.0 * 4.0)            # un-normalised: energy × area
    assert L["Zero"].is_delta and L["Zero"].power == 0.0     # Cycles renders no light from it
    assert "area light 'Zero' has zero size: Cycles renders no light from it, and neither does Penumbra" in s.warnings


def test_light_linking_is_named_in_a_warning(scn):
    """Light and shadow linking (Blender 4.0+) are not modelled: the light reaches and is blocked by every
    object, and a warning names the light, once."""
    lamp = _light(scn, "Linked", "POINT", energy=10)
    _light(scn, "Plain", "POINT", energy=10)
    assert not any("linking" in w for w in snap().warnings)
    lamp.light_linking.blocker_collection = bpy.data.collections.new("Blockers")
    s = snap()
    assert [w for w in s.warnings if "linking" in w] == [
        "light 'Linked' uses light or shadow linking, which Penumbra does not model: every object receives its "
        "light and blocks it"]
    assert {light.name for light in s.lights} >= {"Linked", "Plain"}


def test_no_lights_is_not_an_extraction_error(scn):
    bpy.data.objects.remove(bpy.data.objects["Key"])
    add_cube(scn)
    s = snap()
    assert s.lights == []       # the pipeline warns about it (tests/test_pipeline.py)


# ----------------------------------------------------------------------------------------------------------
# camera
# ----------------------------------------------------------------------------------------------------------

def _project(cam, p):
    clip = cam.projection @ cam.view @ np.append(p, 1.0)
    ndc = clip[:3] / clip[3]
    return (ndc[0] + 1) / 2 * cam.width, (ndc[1] + 1) / 2 * cam.height


def test_camera_perspective_matches_blender(scn):
    cam_ob = scn.camera
    cam_ob.location, cam_ob.rotation_euler = (1, -2, 3), (1.1, 0.0, 0.4)
    cam_ob.scale = (2, 2, 2)                                # camera scale must not leak into the view
    s = snap()
    dg = bpy.context.evaluated_depsgraph_get()
    ref = np.array(cam_ob.evaluated_get(dg).calc_matrix_camera(dg, x=320, y=240, scale_x=1, scale_y=1))
    assert np.allclose(s.camera.projection, ref)
    assert (s.camera.width, s.camera.height) == (320, 240) and not s.camera.is_ortho
    assert np.allclose(s.camera.position, [1, -2, 3])
    assert np.allclose(s.camera.view[:3, :3] @ s.camera.view[:3, :3].T, np.eye(3), atol=1e-6)
    # A point on the optical axis lands in the image centre.
    axis = np.array(cam_ob.matrix_world.to_3x3().normalized() @ Vector((0, 0, -1)))
    x, y = _project(s.camera, np.array([1, -2, 3]) + 7.0 * axis)
    assert np.isclose(x, 160) and np.isclose(y, 120)


def test_camera_known_point_shift_sensor_fit_and_percentage(scn):
    sc = scn
    cam = sc.camera.data
    cam.lens, cam.sensor_width, cam.sensor_fit = 50.0, 36.0, "HORIZONTAL"
    cam.shift_x = 0.1
    sc.render.resolution_percentage = 50
    s = snap()
    assert (s.camera.width, s.camera.height) == (160, 120)
    # Camera at (0,0,10) looking down -Z. World point (1, 0.5, 0): camera-space (1, 0.5, -10).
    # Horizontal fit: x_ndc = 2·lens/sensor · x/d - 2·shift, y_ndc = 2·lens/sensor · (W/H) · y/d.
    k = 2 * 50.0 / 36.0
    x, y = _project(s.camera, np.array([1.0, 0.5, 0.0]))
    assert np.isclose(x, (k * 0.1 - 2 * 0.1 + 1) / 2 * 160, atol=1e-3)   # shifting right moves content left
    assert np.isclose(y, (k * 160 / 120 * 0.05 + 1) / 2 * 120, atol=1e-3)
    # Vertical sensor fit with the same sensor size changes the scale.
    cam.sensor_fit, cam.sensor_height, cam.shift_x = "VERTICAL", 24.0, 0.0
    s = snap()
    kv = 2 * 50.0 / 24.0
    x, y = _project(s.camera, np.array([1.0, 0.5, 0.0]))
    assert np.isclose(y, (kv * 0.05 + 1) / 2 * 120, atol=1e-3)
    assert np.isclose(x, (kv * 120 / 160 * 0.1 + 1) / 2 * 160, atol=1e-3)


def test_camera_ortho_and_override_size(scn):
    cam = scn.camera.data
    cam.type, cam.ortho_scale = "ORTHO", 8.0
    cam.clip_start, cam.clip_end = 0.5, 50.0
    s = snap(width=400, height=200)
    assert s.camera.is_ortho and (s.camera.width, s.camera.height) == (400, 200)
    assert (s.camera.clip_start, s.camera.clip_end) == (0.5, 50.0)
    dg = bpy.context.evaluated_depsgraph_get()
    ref = np.array(scn.camera.evaluated_get(dg).calc_matrix_camera(dg, x=400, y=200, scale_x=1, scale_y=1))
    assert np.allclose(s.camera.projection, ref)
    # ortho_scale spans the larger dimension: x = 2 world units -> 2 / 8 of the width right of centre.
    x, y = _project(s.camera, np.array([2.0, 1.0, -30.0]))
    assert np.isclose(x, 200 + 400 * 2 / 8) and np.isclose(y, 100 + 400 * 1 / 8)


def test_no_camera_names_the_scene(scn):
    scn.name = "Studio"
    scn.camera = None
    add_cube(scn)
    with pytest.raises(ValueError, match="Scene 'Studio' has no camera"):
        snap()


# ----------------------------------------------------------------------------------------------------------
# speed
# ----------------------------------------------------------------------------------------------------------

def test_million_triangle_extraction_time(scn):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=708, y_subdivisions=708, size=10)   # ~1.0M triangles
    ob = bpy.context.active_object
    ob.rotation_euler = (0.1, 0.2, 0.3)
    ob.scale = (1.0, 2.0, 1.0)                 # non-uniform: exercises the general normal path
    dg = bpy.context.evaluated_depsgraph_get()
    scene_mod.extract(dg)                      # warm-up (lazy triangulation inside Blender)
    t0, c0 = time.perf_counter(), time.process_time()
    s = scene_mod.extract(dg)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"\nextract: {s.triangle_count} triangles in {wall * 1e3:.0f} ms wall, {cpu * 1e3:.0f} ms CPU")
    assert s.triangle_count > 1_000_000
    assert wall < 3.0


def test_million_triangles_from_instances_time(scn):
    """~90k geometry-nodes instances of a 12-triangle cube: the per-instance Python loop dominates."""
    ng = _gn_instance_on_points()
    grid = ng.nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Vertices X"].default_value = 300
    grid.inputs["Vertices Y"].default_value = 300
    iop = next(n for n in ng.nodes if n.bl_idname == "GeometryNodeInstanceOnPoints")
    ng.links.new(grid.outputs[0], iop.inputs["Points"])
    host = add_mesh(scn, "Host", [], [])
    host.modifiers.new("gn", "NODES").node_group = ng
    dg = bpy.context.evaluated_depsgraph_get()
    scene_mod.extract(dg)
    t0, c0 = time.perf_counter(), time.process_time()
    s = scene_mod.extract(dg)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"\nextract: {s.triangle_count} triangles from 90000 instances in {wall * 1e3:.0f} ms wall, "
          f"{cpu * 1e3:.0f} ms CPU")
    assert s.triangle_count == 90000 * 12
    assert wall < 3.0


def test_textured_area_light(scn):
    """An Image Texture feeding the Emission colour becomes Light.texture (linear, mean 1), its mean
    colour folded into the light colour."""
    ld = bpy.data.objects["Key"].data
    ld.type = "AREA"
    ld = bpy.data.objects["Key"].data
    ld.use_nodes = True
    img = bpy.data.images.new("tex", 4, 2)
    px = np.zeros((2, 4, 4), np.float32)
    px[..., 3] = 1.0
    px[:, :2, 0] = 1.0          # left half red, right half green (sRGB 1.0 = linear 1.0)
    px[:, 2:, 1] = 1.0
    img.pixels.foreach_set(px.ravel())
    tex = ld.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    emission = next(n for n in ld.node_tree.nodes if n.type == "EMISSION")
    ld.node_tree.links.new(tex.outputs["Color"], emission.inputs["Color"])
    s = snap()
    light = s.lights[0]
    assert light.texture.shape == (2, 4, 3)
    np.testing.assert_allclose(light.texture.reshape(-1, 3).mean(axis=0)[:2], [1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(light.color[:2] / np.asarray(ld.color)[:2], [0.5, 0.5], atol=1e-6)
