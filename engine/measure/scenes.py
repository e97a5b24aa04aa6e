"""Built-in test scenes, built in code with the bpy data API.

Used by the command line (``python -m penumbra render --scene NAME``), the tests and the benchmarks.
Every scene is deterministic (the only randomness is seeded) and has

* one light named "Light" (an AREA light emitting along its local -Z; `room` has a sphere light,
  `flattened` and `slab` a sun), powered so that the unshadowed ground near
  the shadow has a Lambertian radiance of about ``TARGET_RADIANCE`` (ground albedo ``GROUND_ALBEDO``);
* a large receiver plane named "Ground" (z = 0, albedo 0.8 grey; `textured` a checker image) that fills the
  camera's view;
* a camera named "Camera" framing the shadow so that the penumbra covers a good part of the image;
* a black world, so that in Cycles the only direct light is the area light.

Units: metres, Z up. The render engine is left alone (the caller picks it); so are Cycles' sample and
bounce settings.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from typing import Callable

import numpy as np

import bpy
import bmesh
from mathutils import Euler, Matrix, Vector

GROUND_ALBEDO = 0.8
OCCLUDER_RGB = (0.8, 0.35, 0.2)     # a warm orange, distinct from the grey ground
TARGET_RADIANCE = 0.8               # radiance of the lit ground at the scene's reference point
GROUND_NAME = "Ground"
LIGHT_NAME = "Light"
CAMERA_NAME = "Camera"


# --------------------------------------------------------------------------------------------------
# Helpers shared by all scenes
# --------------------------------------------------------------------------------------------------

def diffuse_material(name: str, rgb) -> bpy.types.Material:
    """A node material whose Cycles response is pure Lambertian with albedo `rgb`.

    This is the one place where materials are made; change the node set-up here only.
    Principled BSDF with no specular layer and roughness 1 renders identically to a Diffuse BSDF in
    Cycles 5.0 (checked: same pixel values under an area light with max_bounces 0).
    """
    mat = bpy.data.materials.new(name)
    nt = mat.node_tree                      # new materials come with Principled BSDF + Material Output
    if nt is None:                          # older Blender: node tree only after use_nodes
        mat.use_nodes = True
        nt = mat.node_tree
    bsdf = next((n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)
    out = next((n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    if bsdf is None:
        bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    if out is None:
        out = nt.nodes.new("ShaderNodeOutputMaterial")
    rgba = (float(rgb[0]), float(rgb[1]), float(rgb[2]), 1.0)
    bsdf.inputs["Base Color"].default_value = rgba
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Coat Weight"].default_value = 0.0
    bsdf.inputs["Sheen Weight"].default_value = 0.0
    bsdf.inputs["Transmission Weight"].default_value = 0.0
    bsdf.inputs["Emission Strength"].default_value = 0.0
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = rgba                # viewport / solid-mode colour, also read by simple exporters
    return mat


def _setup_scene(scene: bpy.types.Scene, resolution) -> None:
    """Scene-level settings shared by every built-in scene."""
    scene.render.resolution_x = int(resolution[0])
    scene.render.resolution_y = int(resolution[1])
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    # Linear, untouched display so PNGs show radiance directly (EXR output is scene-linear anyway).
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.world = black_world("World")


def black_world(name: str) -> bpy.types.World:
    """A world that emits nothing, so Cycles' light comes from the lights alone."""
    world = bpy.data.worlds.new(name)
    world.color = (0.0, 0.0, 0.0)
    if world.node_tree is not None:
        for node in world.node_tree.nodes:
            if node.bl_idname == "ShaderNodeBackground":
                node.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
                node.inputs["Strength"].default_value = 0.0
    return world


def mesh_from_bmesh(bm, name: str) -> bpy.types.Mesh:
    """A new mesh of `bm`'s vertices and faces, the faces in an order fixed by their vertices (and frees
    `bm`). bmesh's primitive operators hand out their faces in an order that changes from run to run (it
    follows memory addresses): the triangles' order and so every float sum over them changed between two
    builds of the same scene, errors moved in their last digits, and the Cycles reference cache, which hashes
    the face corners, missed on every run. Faces are sorted by their vertex lists read from the lowest index;
    each keeps its own corner order, which decides how a quad is split into triangles."""
    bm.verts.index_update()
    verts = [tuple(v.co) for v in bm.verts]
    faces = [[v.index for v in face.verts] for face in bm.faces]
    bm.free()

    def from_lowest(ring):
        first = ring.index(min(ring))
        return ring[first:] + ring[:first]
    me = bpy.data.meshes.new(name)
    me.from_pydata(verts, [], sorted(faces, key=from_lowest))
    me.update()
    return me


def _link(scene, obj):
    scene.collection.objects.link(obj)
    return obj


def _mesh_object(scene, name, verts, faces, material, *, smooth=False, matrix=None):
    """Object from python/numpy vertex and face lists (small meshes)."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, v)) for v in verts], [], [tuple(map(int, f)) for f in faces],
                   shade_flat=not smooth)
    me.update()
    me.materials.append(material)
    obj = bpy.data.objects.new(name, me)
    if matrix is not None:
        obj.matrix_world = matrix
    return _link(scene, obj)


def _box_geometry(center, size):
    """8 vertices and 6 outward quads of an axis-aligned box."""
    c = np.asarray(center, float)
    h = np.asarray(size, float) / 2.0
    signs = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                      [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float)
    verts = c + signs * h
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return verts, faces


def _add_box(scene, name, center, size, material):
    verts, faces = _box_geometry(center, size)
    return _mesh_object(scene, name, verts, faces, material)


def _add_ground(scene, half_size=20.0, material=None):
    """The receiver: a single quad at z = 0, normal +Z, big enough to fill every camera view."""
    material = material or diffuse_material("GroundMaterial", (GROUND_ALBEDO,) * 3)
    s = half_size
    return _mesh_object(scene, GROUND_NAME, [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)],
                        [(0, 1, 2, 3)], material)


def _look_at_matrix(location, target, up=(0.0, 0.0, 1.0)) -> Matrix:
    """World matrix of an object at `location` whose local -Z points at `target` (local Y towards `up`)."""
    loc = Vector(location)
    forward = (Vector(target) - loc).normalized()
    upv = Vector(up).normalized()
    if abs(forward.dot(upv)) > 0.999:               # looking (almost) along `up`: use another up
        upv = Vector((0.0, 1.0, 0.0)) if abs(forward.y) < 0.9 else Vector((0.0, 0.0, 1.0))
    z = -forward
    x = upv.cross(z).normalized()
    y = z.cross(x)
    rot = Matrix((x, y, z)).transposed()            # columns: local X, Y, Z in world space
    m = rot.to_4x4()
    m.translation = loc
    return m


def _add_camera(scene, location, target, lens=35.0, up=(0.0, 0.0, 1.0)):
    cam = bpy.data.cameras.new(CAMERA_NAME)
    cam.lens = lens
    cam.sensor_fit = "AUTO"
    cam.sensor_width = 36.0
    cam.clip_start = 0.05
    cam.clip_end = 200.0
    obj = _link(scene, bpy.data.objects.new(CAMERA_NAME, cam))
    obj.matrix_world = _look_at_matrix(location, target, up)
    scene.camera = obj
    return obj


def _irradiance_per_watt(matrix: Matrix, size_x: float, size_y: float, point, normal) -> float:
    """Irradiance (W/m²) at `point` (surface `normal`) from an unoccluded rectangular AREA light of 1 W: the
    analytic formula the renderer itself uses (engine/core/irradiance.py, checked against Cycles)."""
    from ..core.irradiance import irradiance
    from ..core.snapshot import AREA, RECTANGLE, Light
    m = np.array(matrix, dtype=float)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)
    light = Light("probe", AREA, m, np.ones(3), 1.0, RECTANGLE, float(size_x), float(size_y))
    return float(irradiance(light, np.asarray([point], float), np.asarray([normal], float))[0, 0])


def _add_area_light(scene, location, target, size, *, reference_point=(0.0, 0.0, 0.0),
                    reference_normal=(0.0, 0.0, 1.0), size_y=None, radiance=TARGET_RADIANCE):
    """A square (or rectangular) AREA light at `location` aimed at `target`.

    Its power is chosen so that an unshadowed Lambertian surface of albedo GROUND_ALBEDO at
    `reference_point` has outgoing radiance `radiance`.
    """
    data = bpy.data.lights.new(LIGHT_NAME, "AREA")
    if size_y is None:
        data.shape = "SQUARE"
        data.size = size
        sy = size
    else:
        data.shape = "RECTANGLE"
        data.size = size
        data.size_y = size_y
        sy = size_y
    data.color = (1.0, 1.0, 1.0)
    data.use_shadow = True
    data.spread = math.pi
    if hasattr(data, "normalize"):
        data.normalize = True
    if hasattr(data, "exposure"):
        data.exposure = 0.0
    obj = _link(scene, bpy.data.objects.new(LIGHT_NAME, data))
    obj.matrix_world = _look_at_matrix(location, target, up=(0.0, 1.0, 0.0))
    e = _irradiance_per_watt(obj.matrix_world, size, sy, reference_point, reference_normal)
    data.energy = radiance / (GROUND_ALBEDO / math.pi * e)
    return obj


# --------------------------------------------------------------------------------------------------
# The scenes
# --------------------------------------------------------------------------------------------------

def _plate_under_square_light(scene):
    """`plane`'s plate, light and camera (also under `textured`'s checker ground)."""
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    s = 0.5
    _mesh_object(scene, "Occluder", [(-s, -s, 0.8), (s, -s, 0.8), (s, s, 0.8), (-s, s, 0.8)],
                 [(0, 1, 2, 3)], occ)
    _add_area_light(scene, (0, 0, 2.5), (0, 0, 0), 1.5, reference_point=(1.2, 0.0, 0.0))
    _add_camera(scene, (0.0, -2.1, 2.0), (0.0, -0.2, 0.0), lens=35)


def _build_plane(scene):
    """A 1 m square plate parallel to a 1.5 m square light, halfway-ish down: the shadow is nearly all
    penumbra (umbra only |x|, |y| < 0.38 m, penumbra out to 1.09 m) -- Atty et al.'s worst case."""
    _add_ground(scene)
    _plate_under_square_light(scene)


def _build_suzanne(scene):
    """Suzanne (subdivision level 1, smooth) floating over the ground."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    bm = bmesh.new()
    bmesh.ops.create_monkey(bm)
    me = mesh_from_bmesh(bm, "Suzanne")
    me.shade_smooth()
    me.materials.append(occ)
    obj = _link(scene, bpy.data.objects.new("Suzanne", me))
    # Face the monkey upwards a little (towards the light) and float it 1.2 m above the ground.
    obj.matrix_world = (Matrix.Translation((0.0, 0.0, 1.2)) @ Matrix.Rotation(math.radians(-35), 4, "X")
                        @ Matrix.Scale(0.7, 4))
    mod = obj.modifiers.new("Subdivision", "SUBSURF")
    mod.levels = 1
    mod.render_levels = 1
    _add_area_light(scene, (0, 0, 3.5), (0, 0, 0), 2.0, reference_point=(1.5, 0.0, 0.0))
    _add_camera(scene, (0.5, -3.0, 2.8), (0.0, 0.0, 0.3), lens=35)


def _build_balls(scene):
    """3x3x3 UV spheres on a lattice tilted by (25, 15, 10) degrees, so that seen from the light the
    balls of different layers overlap partially: overlapping occluders at different depths."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=32, v_segments=16, radius=0.2)
    me = mesh_from_bmesh(bm, "Ball")
    me.shade_smooth()
    me.materials.append(occ)
    spacing = 0.5
    tilt = Euler((math.radians(25), math.radians(15), math.radians(10)), "XYZ").to_matrix()
    centre = Vector((0.0, 0.0, 1.3))
    for k in range(3):                  # layers, bottom to top
        for j in range(3):
            for i in range(3):
                obj = _link(scene, bpy.data.objects.new(f"Ball.{k}{j}{i}", me))
                obj.location = centre + tilt @ (Vector((i - 1, j - 1, k - 1)) * spacing)
    # Light a little behind the lattice so the shadow falls in front of it, towards the camera.
    _add_area_light(scene, (-0.6, 1.2, 4.0), (-0.6, 1.2, 0.0), 1.5, reference_point=(-0.6, 1.2, 0.0))
    _add_camera(scene, (0.6, -3.4, 3.2), (0.3, -0.6, 0.2), lens=35)


def _build_silhouette(scene):
    """Two stacked plates whose silhouette depends on where on the light you stand.

    Light: 2 m square at z = 4 (corners at x, y = +-1). Upper plate: 1.2 m square at z = 2, centred.
    Lower plate: a bar at z = 1 spanning x in [0.3, 0.85], y in [-0.85, 0.85].
    From the light centre the upper plate hides everything at z = 1 within |x|, |y| < 0.6 * 3/2 = 0.9,
    so the lower bar is completely hidden and the silhouette is just a square. From the light corner
    (1, 1, 4) the upper plate hides only x, y in [-1.4, 0.4] at z = 1, so the part of the bar with
    x > 0.4 pokes out and the silhouette becomes an L. Techniques that take one silhouette (or one shadow
    map) from the light centre miss the lower plate's contribution to the penumbra on the +x side.
    """
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    lower = diffuse_material("LowerOccluderMaterial", (0.25, 0.45, 0.8))
    s = 0.6
    _mesh_object(scene, "Occluder", [(-s, -s, 2.0), (s, -s, 2.0), (s, s, 2.0), (-s, s, 2.0)],
                 [(0, 1, 2, 3)], occ)
    _mesh_object(scene, "LowerOccluder",
                 [(0.3, -0.85, 1.0), (0.85, -0.85, 1.0), (0.85, 0.85, 1.0), (0.3, 0.85, 1.0)],
                 [(0, 1, 2, 3)], lower)
    _add_area_light(scene, (0, 0, 4.0), (0, 0, 0), 2.0, reference_point=(1.8, 0.0, 0.0))
    _add_camera(scene, (0.3, -3.6, 2.4), (0.2, -0.2, 0.0), lens=30)


def _build_contact(scene):
    """A cube and a cylinder resting on the ground (bottoms exactly at z = 0): contact shadows, from
    hard at the contact line to soft further away. The light is off to one side."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    verts, faces = _box_geometry((0.0, 0.0, 0.5), (1.0, 1.0, 1.0))
    cube = _mesh_object(scene, "Cube", verts, faces, occ)
    cube.matrix_world = Matrix.Translation((-0.4, 0.0, 0.0)) @ Matrix.Rotation(math.radians(30), 4, "Z")
    bm = bmesh.new()
    bmesh.ops.create_cone(bm, cap_ends=True, cap_tris=False, segments=48, radius1=0.3, radius2=0.3,
                          depth=1.4, matrix=Matrix.Translation((0.0, 0.0, 0.7)))
    me = mesh_from_bmesh(bm, "Cylinder")
    me.materials.append(occ)
    cyl = _link(scene, bpy.data.objects.new("Cylinder", me))
    cyl.location = (0.7, 0.8, 0.0)
    _add_area_light(scene, (-1.6, -0.6, 3.2), (0.0, 0.2, 0.0), 1.0, reference_point=(-0.4, -0.8, 0.0))
    _add_camera(scene, (2.4, -2.6, 2.2), (0.5, 0.4, 0.2), lens=35)


def _bars(axis: int, count: int, pitch: float, width: float, length: float, z: float):
    """Vertices and quads of `count` thin square-section bars along world axis `axis` (0 = x, 1 = y)."""
    offsets = (np.arange(count) - (count - 1) / 2.0) * pitch
    verts, faces = [], []
    for o in offsets:
        centre = [0.0, 0.0, z]
        size = [width, width, width]
        centre[1 - axis] = o
        size[axis] = length
        v, f = _box_geometry(centre, size)
        base = len(verts)
        verts.extend(v)
        faces.extend(tuple(i + base for i in q) for q in f)
    return verts, faces


def _build_thin(scene):
    """A 2 m x 2 m woven grid of 2 mm bars at 1 cm pitch, 0.6 m above the ground (bars thinner than a
    texel of a 1024^2 shadow map over the 4 m region: 3.9 mm). Each direction covers 20 % of the area, so
    the exact shadow is a smooth ~36 % darkening with soft edges; undersampled shadow maps show moire
    or miss the bars."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    width, pitch, length, count = 0.002, 0.01, 2.0, 200
    vx, fx = _bars(0, count, pitch, width, length, 0.6)
    vy, fy = _bars(1, count, pitch, width, length, 0.6 + width)
    faces = fx + [tuple(i + len(vx) for i in q) for q in fy]
    _mesh_object(scene, "Fence", vx + vy, faces, occ)
    _add_area_light(scene, (0, 0, 3.0), (0, 0, 0), 1.0)
    _add_camera(scene, (0.0, -3.0, 2.6), (0.0, -0.2, 0.0), lens=35)


def _city_mesh(name: str, nx: int, ny: int, pitch: float, footprint: float, seed: int) -> bpy.types.Mesh:
    """nx * ny boxes (4 walls + roof, no floor: 10 triangles each) on a regular grid, heights seeded."""
    rng = np.random.default_rng(seed)
    heights = np.exp(rng.normal(math.log(0.18), 0.55, size=(ny, nx))).clip(0.04, 0.9)
    jitter = rng.uniform(-0.15, 0.15, size=(ny, nx, 2)) * (pitch - footprint)
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    cx = (ix - (nx - 1) / 2.0) * pitch + jitter[..., 0]
    cy = (iy - (ny - 1) / 2.0) * pitch + jitter[..., 1]
    n = nx * ny
    cx, cy, h = cx.ravel(), cy.ravel(), heights.ravel()
    half = footprint / 2.0
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * half      # counter-clockwise
    verts = np.zeros((n, 8, 3), np.float32)
    verts[:, :4, 0] = cx[:, None] + corners[:, 0]
    verts[:, :4, 1] = cy[:, None] + corners[:, 1]
    verts[:, 4:, :2] = verts[:, :4, :2]
    verts[:, 4:, 2] = h[:, None]
    quads = np.array([[4, 5, 6, 7],                                          # roof
                      [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]], np.int32)  # walls
    loops = (quads[None, :, :] + 8 * np.arange(n, dtype=np.int32)[:, None, None]).ravel()
    nquads = n * len(quads)

    me = bpy.data.meshes.new(name)
    me.vertices.add(n * 8)
    me.vertices.foreach_set("co", verts.ravel())
    me.loops.add(loops.size)
    me.loops.foreach_set("vertex_index", loops)
    me.polygons.add(nquads)
    me.polygons.foreach_set("loop_start", np.arange(0, 4 * nquads, 4, dtype=np.int32))
    me.update(calc_edges=True)
    me.shade_flat()
    return me


def _build_city(scene):
    """150 x 150 boxes of seeded heights (225k triangles) in a single mesh over a 12 m square."""
    _add_ground(scene)
    me = _city_mesh("City", 150, 150, pitch=0.08, footprint=0.055, seed=20240607)
    me.materials.append(diffuse_material("CityMaterial", (0.7, 0.7, 0.75)))
    _link(scene, bpy.data.objects.new("City", me))
    _add_area_light(scene, (0, 0, 5.0), (0, 0, 0), 2.0)
    _add_camera(scene, (0.0, -1.9, 1.5), (0.0, -0.3, 0.0), lens=35)


def _build_grazing(scene):
    """Light at 5 deg elevation, 20 m away: its rays meet the ground at about 85 deg from the normal.
    A post and a floating bar throw long, stretched shadows; the light's 2.5 m extent spans ~7 deg of
    elevation, so the penumbra along the shadow is very long. (Far away so the ground's radiance, which
    falls like 1/r^3 at grazing incidence, varies by less than 2x across the frame.)"""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    _add_box(scene, "Post", (0.0, 0.0, 0.25), (0.2, 0.2, 0.5), occ)
    _add_box(scene, "Occluder", (0.0, 0.8, 0.35), (0.15, 0.6, 0.1), occ)
    dist = 20.0
    elev = math.radians(5.0)
    light_pos = (-dist * math.cos(elev), 0.0, dist * math.sin(elev))
    _add_area_light(scene, light_pos, (0.0, 0.0, 0.0), 2.5, reference_point=(1.6, -0.6, 0.0))
    _add_camera(scene, (1.6, -1.4, 4.0), (1.6, 0.3, 0.0), lens=35)


def _power_for_radiance(obj, point, normal, radiance=TARGET_RADIANCE) -> None:
    """Set any light's power so that an unshadowed ground at `point` (surface `normal`) has Lambertian
    radiance `radiance`, through the renderer's own light conventions (extraction + analytic irradiance)."""
    from ..blender.extract import make_light
    from ..core.irradiance import irradiance
    obj.data.energy = 1.0
    light = make_light(obj.name, obj.data, np.array(obj.matrix_world, float), lambda _text: None)
    e = float(irradiance(light, np.asarray([point], float), np.asarray([normal], float))[0, 1])
    obj.data.energy = radiance / (GROUND_ALBEDO / math.pi * e)


def _add_sun(scene, direction_to_sun, angle, *, reference_normal=(0.0, 0.0, 1.0)):
    """A SUN light shining along -`direction_to_sun` with angular diameter `angle` (radians)."""
    data = bpy.data.lights.new(LIGHT_NAME, "SUN")
    data.angle = float(angle)
    data.use_shadow = True
    obj = _link(scene, bpy.data.objects.new(LIGHT_NAME, data))
    d = Vector(direction_to_sun).normalized()
    obj.matrix_world = _look_at_matrix(d * 10.0, (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    _power_for_radiance(obj, (0.0, 0.0, 0.0), reference_normal)
    return obj


def _uv_sphere_mesh(name, radius, material, u=32, v=16):
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=u, v_segments=v, radius=radius)
    me = mesh_from_bmesh(bm, name)
    me.shade_smooth()
    me.materials.append(material)
    return me


def _build_cube(scene):
    """Blender's default cube (2 m, flat-shaded) resting on the floor under a 3 m overhead area light,
    seen from the default camera's side: its side faces are edge-on from the light centre and lit by the
    rest of the light (grazing receivers, where shadow maps show acne and half-lit faces)."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    _add_box(scene, "Cube", (0.0, 0.0, 1.0), (2.0, 2.0, 2.0), occ)
    _add_area_light(scene, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0), 3.0, reference_point=(2.5, 0.0, 0.0))
    _add_camera(scene, (7.36, -6.93, 4.96), (0.0, 0.0, 0.6), lens=50)


def _build_tilted(scene):
    """A floor tilted 25 degrees about X with a sphere resting on it, under a 2 m x 1 m rectangle light:
    a receiver that is not perpendicular to the light axis (PCSS's blocker search meets the floor itself)."""
    tilt = Matrix.Rotation(math.radians(25.0), 4, "X")
    ground = _add_ground(scene, half_size=8.0)
    ground.matrix_world = tilt
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    radius = 0.5
    sphere = _link(scene, bpy.data.objects.new("Sphere", _uv_sphere_mesh("Sphere", radius, occ)))
    normal = tilt.to_3x3() @ Vector((0.0, 0.0, 1.0))
    sphere.location = normal * radius               # touching the floor at the origin
    _add_area_light(scene, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0), 2.0, size_y=1.0,
                    reference_point=(1.4, 0.0, 0.0), reference_normal=tuple(normal))
    _add_camera(scene, (0.6, -3.6, 3.2), (0.2, 0.0, 0.2), lens=35)


def _build_room(scene):
    """A closed 6 x 5 x 3 m room (floor, walls and ceiling facing inwards) lit by a 0.15 m sphere light
    under the ceiling, a box and a sphere on the floor: receivers on every side of a point-like light."""
    material = diffuse_material("GroundMaterial", (GROUND_ALBEDO,) * 3)
    hx, hy, h = 3.0, 2.5, 3.0
    _mesh_object(scene, GROUND_NAME, [(-hx, -hy, 0), (hx, -hy, 0), (hx, hy, 0), (-hx, hy, 0)],
                 [(0, 1, 2, 3)], material)
    verts, faces = _box_geometry((0.0, 0.0, h / 2.0), (2 * hx, 2 * hy, h))
    inward = [tuple(reversed(f)) for f in faces[1:]]          # no floor quad; winding turned inwards
    _mesh_object(scene, "Walls", verts, inward, material)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    _add_box(scene, "Box", (0.6, 0.4, 0.4), (0.8, 0.8, 0.8), occ)
    sphere = _link(scene, bpy.data.objects.new("Ball", _uv_sphere_mesh("Ball", 0.35, occ)))
    sphere.location = (-0.9, -0.5, 0.35)
    data = bpy.data.lights.new(LIGHT_NAME, "POINT")
    data.shadow_soft_size = 0.15
    data.use_shadow = True
    obj = _link(scene, bpy.data.objects.new(LIGHT_NAME, data))
    obj.location = (0.0, 0.0, 2.4)
    bpy.context.view_layer.update()
    _power_for_radiance(obj, (1.5, -1.0, 0.0), (0.0, 0.0, 1.0))
    _add_camera(scene, (2.6, -2.2, 2.2), (-0.2, 0.3, 0.4), lens=22)


def _build_flattened(scene):
    """Casters with one object scale axis at 0 under a slightly soft sun: a torus squashed flat into a
    ring (scale z = 0) floating over the ground and a cube squashed into a vertical wall (scale y = 0).
    Their matrices are singular, yet Cycles shadows them."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    bm = bmesh.new()
    segments, sides, big, small = 32, 12, 0.6, 0.2
    rings = []
    for i in range(segments):
        a = 2 * math.pi * i / segments
        ring = []
        for j in range(sides):
            b = 2 * math.pi * j / sides
            r = big + small * math.cos(b)
            ring.append(bm.verts.new((r * math.cos(a), r * math.sin(a), small * math.sin(b))))
        rings.append(ring)
    for i in range(segments):
        for j in range(sides):
            a, b = rings[i], rings[(i + 1) % segments]
            bm.faces.new((a[j], b[j], b[(j + 1) % sides], a[(j + 1) % sides]))
    me = mesh_from_bmesh(bm, "Torus")
    me.shade_smooth()
    me.materials.append(occ)
    torus = _link(scene, bpy.data.objects.new("Torus", me))
    torus.matrix_world = Matrix.Translation((-0.7, 0.3, 1.0)) @ Matrix.Diagonal((1.0, 1.0, 0.0, 1.0))
    wall = _add_box(scene, "Wall", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), occ)
    wall.matrix_world = (Matrix.Translation((1.0, -0.3, 0.6)) @ Matrix.Rotation(math.radians(20), 4, "Z")
                         @ Matrix.Diagonal((1.2, 0.0, 1.2, 1.0)))
    _add_sun(scene, (-0.35, 0.25, 1.0), 0.08)
    _add_camera(scene, (0.8, -3.8, 3.4), (0.2, 0.4, 0.0), lens=35)


def _build_slab(scene):
    """A thin upright slab (1.6 x 1.0 x 0.04 m) whose face the sun meets at 10 degrees, with the sun 0.5 rad
    wide: part of the sun's disk lies below the face's tangent plane (no light, not a shadow) and the face
    is lit by the rest. The ground sees the sun at 50 degrees elevation."""
    _add_ground(scene)
    occ = diffuse_material("OccluderMaterial", OCCLUDER_RGB)
    elevation = math.radians(50.0)
    to_sun = Vector((math.cos(elevation), 0.0, math.sin(elevation)))
    # the face normal is horizontal at azimuth a with cos(elevation)·cos(a) = cos(80°)
    azimuth = math.acos(math.cos(math.radians(80.0)) / math.cos(elevation))
    slab = _add_box(scene, "Slab", (0.0, 0.0, 0.0), (1.6, 0.04, 1.0), occ)
    # box local -Y/+Y are the big faces; turn local +Y onto the face normal
    slab.matrix_world = (Matrix.Translation((0.0, 0.0, 0.5))
                         @ Matrix.Rotation(azimuth - math.pi / 2.0, 4, "Z"))
    _add_sun(scene, to_sun, 0.5)
    face = Vector((math.cos(azimuth), math.sin(azimuth), 0.0))
    _add_camera(scene, tuple(face * 3.2 + Vector((0.4, 0.0, 1.6))), (0.0, 0.0, 0.4), lens=35)


Builder = Callable[[bpy.types.Scene], None]

CHECKER_RGB = ((0.85, 0.8, 0.7), (0.15, 0.25, 0.45))   # the textured ground's two squares, sRGB values


def checker_image(name: str, size: int = 64, cells: int = 8, colours=CHECKER_RGB) -> bpy.types.Image:
    """An 8-bit sRGB checker image made in code (`cells` × `cells` squares), packed into the file so a saved
    .blend keeps it."""
    img = bpy.data.images.new(name, size, size, alpha=False, float_buffer=False)
    y, x = np.mgrid[0:size, 0:size] * cells // size
    rgba = np.ones((size, size, 4), np.float32)
    rgba[..., :3] = np.where(((x + y) % 2 == 0)[..., None], colours[0], colours[1])
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    return img


def textured_material(name: str, image, *, repeats: float = 1.0, angle: float = 0.0, offset=(0.0, 0.0),
                      interpolation: str = "Linear", extension: str = "REPEAT") -> bpy.types.Material:
    """diffuse_material whose Base Color is an Image Texture fed by the UV map through a Mapping node (Point
    type): the image repeats `repeats` times across the UV square, turned by `angle` (radians, about Z) and
    moved by `offset`."""
    mat = diffuse_material(name, (1.0, 1.0, 1.0))
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = image, interpolation, extension
    uv = nt.nodes.new("ShaderNodeUVMap")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (repeats, repeats, 1.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, angle)
    mapping.inputs["Location"].default_value = (offset[0], offset[1], 0.0)
    nt.links.new(uv.outputs["UV"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def set_planar_uv(obj, scale: float, offset=(0.5, 0.5)) -> None:
    """A UV map "UVMap" on `obj`'s mesh: (u, v) = offset + (x, y) / scale of each corner's object position."""
    me = obj.data
    layer = me.uv_layers.new(name="UVMap")
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    corner_vert = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", corner_vert)
    uv = co.reshape(-1, 3)[corner_vert, :2] / scale + np.asarray(offset, np.float32)
    layer.uv.foreach_set("vector", uv.astype(np.float32).ravel())


def _build_textured(scene):
    """The `plane` scene on a checkered ground: an 8-bit sRGB checker image (made in code) through UV Map ->
    Mapping (scaled, turned 20 degrees, moved) -> Image Texture, one square per 25 cm; the plate is plain
    orange."""
    ground = _add_ground(scene, material=textured_material("CheckerMaterial", checker_image("Checker"),
                                                           repeats=20.0, angle=math.radians(20.0),
                                                           offset=(0.3, 0.1)))
    set_planar_uv(ground, scale=40.0)
    _plate_under_square_light(scene)


SCENES: "OrderedDict[str, tuple[Builder, str]]" = OrderedDict([
    ("plane", (_build_plane, "square plate parallel to a square area light: almost all penumbra")),
    ("suzanne", (_build_suzanne, "Suzanne (subdivided, smooth) floating over the ground")),
    ("balls", (_build_balls, "3x3x3 grid of spheres, layers offset: overlapping occluders")),
    ("silhouette", (_build_silhouette, "stacked offset plates: silhouette differs from light centre and corners")),
    ("contact", (_build_contact, "cube and cylinder resting on the ground: contact shadows")),
    ("thin", (_build_thin, "woven grid of 2 mm bars, thinner than a 1024^2 shadow-map texel")),
    ("city", (_build_city, "150x150 seeded boxes, 225k triangles in one mesh")),
    ("grazing", (_build_grazing, "light at 5 deg elevation: rays hit the ground at ~85 deg")),
    ("cube", (_build_cube, "Blender's default cube on the floor under an overhead area light: edge-on faces")),
    ("tilted", (_build_tilted, "sphere resting on a floor tilted 25 deg under a rectangle light")),
    ("room", (_build_room, "sphere light inside a closed room with a box and a ball: receivers all around")),
    ("flattened", (_build_flattened, "casters with one scale axis 0 (flat torus, flat cube) under a sun")),
    ("slab", (_build_slab, "thin upright slab lit 10 deg off edge-on by a 0.5 rad sun")),
    ("textured", (_build_textured, "the plane scene on a checker-textured ground (image through UV Map and Mapping)")),
])


def list_scenes() -> list[tuple[str, str]]:
    """(name, one-line description) of every built-in scene, in order."""
    return [(name, desc) for name, (_, desc) in SCENES.items()]


def build(name: str, *, resolution=(256, 256)) -> bpy.types.Scene:
    """Reset Blender to an empty file, build scene `name` into bpy.context.scene and return it."""
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; valid scenes: {', '.join(SCENES)}")
    builder, _ = SCENES[name]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    _setup_scene(scene, resolution)
    builder(scene)
    bpy.context.view_layer.update()
    return scene
