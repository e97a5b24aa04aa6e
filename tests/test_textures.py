"""Textured base colours (issue 15 item 10): images sampled per pixel in the G-buffer, colour attributes,
the extraction of Image Texture / UV Map / Mapping / Texture Coordinate / Color Attribute nodes, and the
textured built-in scene's Combined against Cycles'."""
from __future__ import annotations

import numpy as np
import pytest

from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.core.snapshot import SUN, AlbedoTexture, Camera, Light, ObjectInfo, SceneSnapshot
from penumbra.engine.render import pipeline

# ----------------------------------------------------------------------------------------------------------
# GPU: a snapshot built directly. A ground square [-1, 1]² seen straight down by an orthographic camera, lit by
# a sun straight above of strength S: Unshadowed = albedo / π · S, so each pixel's albedo is read back exactly.
# ----------------------------------------------------------------------------------------------------------

SIZE = 32
S = 3.0
TEXELS = np.array([[[0.9, 0.1, 0.1], [0.1, 0.8, 0.1]],       # row 0 (v = 0): red, green
                   [[0.1, 0.1, 0.7], [0.6, 0.6, 0.1]]],      # row 1 (v = 1): blue, yellow
                  np.float32)


def _ground(uv_of_xy, texture: AlbedoTexture | None, albedo=1.0, corner_color=None) -> SceneSnapshot:
    corners = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]], np.float32)
    normals = np.zeros_like(corners)
    normals[..., 2] = 1.0
    view = np.eye(4)
    view[2, 3] = -5.0                                          # camera at z = 5 looking down, X and Y as the world's
    proj = np.diag([1.0, 1.0, -2.0 / 9.0, 1.0])
    proj[2, 3] = -10.0 / 9.0                                   # near 0.5, far 9.5
    cam = Camera("Camera", view, proj, SIZE, SIZE, is_ortho=True)
    sun = Light("Sun", SUN, np.eye(4), np.ones(3), S)
    snap = SceneSnapshot(corners, normals, np.zeros(2, np.int32), np.full((2, 3), albedo, np.float32),
                         [ObjectInfo("Ground", caster=False)], [sun], cam)
    if texture is not None:
        snap.uv = uv_of_xy(corners[..., :2]).astype(np.float32)
        snap.texture_id = np.zeros(2, np.int32)
        snap.textures = [texture]
    snap.corner_color = corner_color
    return snap


def _albedo(snap) -> np.ndarray:
    out = pipeline.render(snap, RenderSettings(technique="HARD")).passes["Unshadowed"]
    return out * np.pi / S


def _pixel_centres():
    x = -1.0 + (np.arange(SIZE) + 0.5) * 2.0 / SIZE
    return np.meshgrid(x, x)                                   # (row = y, column = x), row 0 at the bottom


def _wrap(t, n, extension):
    """Texel index `t` (integer array) of an n-texel axis → (index, inside) as each extension reads it."""
    if extension == "REPEAT":
        return t % n, np.ones_like(t, bool)
    if extension == "MIRROR":
        m = t % (2 * n)
        return np.where(m < n, m, 2 * n - 1 - m), np.ones_like(t, bool)
    inside = (t >= 0) & (t < n)
    return np.clip(t, 0, n - 1), inside if extension == "CLIP" else np.ones_like(t, bool)


def _sample(u, v, extension, interpolation, texels=TEXELS):
    """A numpy image lookup with OpenGL's (and Cycles') texel-centre convention."""
    h, w = texels.shape[:2]
    if interpolation == "Closest":
        (i, ii), (j, ji) = _wrap(np.floor(u * w).astype(int), w, extension), _wrap(np.floor(v * h).astype(int), h,
                                                                                    extension)
        return texels[j, i] * (ii & ji)[..., None]
    s, t = u * w - 0.5, v * h - 0.5
    s0, t0 = np.floor(s).astype(int), np.floor(t).astype(int)
    fs, ft = (s - s0)[..., None], (t - t0)[..., None]
    out = 0.0
    for dj, wj in ((0, 1 - ft), (1, ft)):
        for di, wi in ((0, 1 - fs), (1, fs)):
            (i, ii), (j, ji) = _wrap(s0 + di, w, extension), _wrap(t0 + dj, h, extension)
            out = out + wi * wj * texels[j, i] * (ii & ji)[..., None]
    return out


@pytest.mark.parametrize("extension", ["REPEAT", "EXTEND", "CLIP", "MIRROR"])
@pytest.mark.parametrize("interpolation", ["Closest", "Linear"])
def test_albedo_image_per_pixel(extension, interpolation):
    """uv = x + 0.5 (and y + 0.5) spans [-0.5, 1.5]: a third of each axis lies outside the image."""
    tex = AlbedoTexture("t", TEXELS, interpolation, extension)
    got = _albedo(_ground(lambda xy: xy + 0.5, tex))
    x, y = _pixel_centres()
    want = _sample(x + 0.5, y + 0.5, extension, interpolation)
    # Half floats hold the texels (relative 5e-4); bilinear weights carry 8 fractional bits on llvmpipe.
    tol = 2e-3 if interpolation == "Closest" else 1e-2
    err = np.abs(got - want).max()
    assert err < tol, f"{extension}/{interpolation}: max |albedo - expected| {err:.4f}"
    # Not the untextured albedo (1.0) anywhere: the image is what the shading reads.
    assert np.abs(got - 1.0).min() > 0.05


def _srgb_decode(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_srgb_bytes_are_decoded_after_filtering():
    """8-bit sRGB images: bilinear on the bytes, then sRGB → linear (Cycles' order, see extract.image_rgb)."""
    codes = np.rint(TEXELS * 255).astype(np.uint8)
    tex = AlbedoTexture("t", codes, "Linear", "EXTEND", srgb=True)
    got = _albedo(_ground(lambda xy: xy * 0.5 + 0.5, tex))
    x, y = _pixel_centres()
    u, v = x * 0.5 + 0.5, y * 0.5 + 0.5
    want = _srgb_decode(_sample(u, v, "EXTEND", "Linear", codes / 255.0))
    decoded_first = _sample(u, v, "EXTEND", "Linear", _srgb_decode(codes / 255.0))
    assert np.abs(got - want).max() < 1e-2
    # The order matters here (the two differ by more than 0.05 between texels), so the check can tell them apart.
    assert np.abs(want - decoded_first).max() > 0.05


def test_albedo_factor_and_corner_colour_multiply_the_image():
    tex = AlbedoTexture("t", TEXELS, "Closest", "EXTEND")
    colour = np.broadcast_to(np.array([0.5, 1.0, 0.25], np.float32), (2, 3, 3)).copy()
    got = _albedo(_ground(lambda xy: xy * 0.5 + 0.5, tex, albedo=0.8, corner_color=colour))
    x, y = _pixel_centres()
    want = _sample(x * 0.5 + 0.5, y * 0.5 + 0.5, "EXTEND", "Closest") * 0.8 * np.array([0.5, 1.0, 0.25])
    assert np.abs(got - want).max() < 2e-3


def test_corner_colours_interpolate_without_a_texture():
    colour = np.zeros((2, 3, 3), np.float32)
    colour[0] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]              # corners (-1,-1), (1,-1), (1,1)
    colour[1] = [[1, 0, 0], [0, 0, 1], [0.5, 0.5, 0.5]]        # corners (-1,-1), (1,1), (-1,1)
    got = _albedo(_ground(None, None, corner_color=colour))
    x, y = _pixel_centres()
    # Triangle 0 (below the diagonal y < x): barycentrics of (x, y) on (-1,-1), (1,-1), (1,1).
    lower = y < x
    b1, b2 = (x - y) / 2.0, (y + 1.0) / 2.0
    want0 = (1 - b1 - b2)[..., None] * [1, 0, 0] + b1[..., None] * [0, 1, 0] + b2[..., None] * [0, 0, 1]
    c1, c2 = (x + 1.0) / 2.0, (y - x) / 2.0
    want1 = (1 - c1 - c2)[..., None] * [1, 0, 0] + c1[..., None] * [0, 0, 1] + c2[..., None] * [0.5, 0.5, 0.5]
    want = np.where(lower[..., None], want0, want1)
    keep = np.abs(x - y) > 2.5 / SIZE                          # the diagonal's pixels belong to either triangle
    assert np.abs(got - want)[keep].max() < 2e-3


def test_textured_draws_leave_depth_maps_alone():
    """Shadows of a textured caster: the depth passes draw positions only, the texture ranges merged."""
    tex = AlbedoTexture("t", TEXELS, "Closest", "REPEAT")
    snap = _ground(lambda xy: xy + 0.5, tex)
    snap.objects[0].caster = True
    plain = _ground(None, None)
    plain.objects[0].caster = True
    a = pipeline.render(snap, RenderSettings(technique="PCSS")).passes["Visibility"]
    b = pipeline.render(plain, RenderSettings(technique="PCSS")).passes["Visibility"]
    assert np.array_equal(a, b)


# ----------------------------------------------------------------------------------------------------------
# Blender: what extraction reads from node trees
# ----------------------------------------------------------------------------------------------------------

@pytest.fixture
def bpy_mod():
    return pytest.importorskip("bpy")


def _snap(bpy):
    from penumbra.engine.blender.extract import extract
    return extract(bpy.context.evaluated_depsgraph_get(), bpy.context.scene)


def _quad_object(bpy, name, material, z=0.0):
    from penumbra.engine.measure import scenes
    ob = scenes._mesh_object(bpy.context.scene, name, [(-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z)],
                             [(0, 1, 2, 3)], material)
    return ob


def _empty_scene(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    from penumbra.engine.measure import scenes
    scenes._add_camera(bpy.context.scene, (0, 0, 5), (0, 0, 0))


def test_builtin_textured_scene_reads_image_uv_and_mapping(bpy_mod):
    bpy = bpy_mod
    from penumbra.engine.measure import scenes
    scenes.build("textured", resolution=(32, 32))
    s = _snap(bpy)
    assert not s.warnings, s.warnings
    names = [o.name for o in s.objects]
    ground = s.object_id == names.index("Ground")
    assert (s.texture_id[ground] == 0).all() and (s.texture_id[~ground] == -1).all()
    tex = s.textures[0]
    assert tex.srgb and tex.pixels.dtype == np.uint8 and tex.pixels.shape == (64, 64, 3)
    assert tex.interpolation == "Linear" and tex.extension == "REPEAT"
    for texel, rgb in ((tex.pixels[0, 0], scenes.CHECKER_RGB[0]), (tex.pixels[0, 8], scenes.CHECKER_RGB[1])):
        assert np.abs(texel - np.array(rgb) * 255).max() <= 0.5 + 1e-3      # the bytes Blender stored
    # Mapping (Point): uv' = T + R_z(20°) (S uv), uv = (x, y) / 40 + 0.5 on the ground's corners.
    xy = s.positions[ground][..., :2].astype(np.float64)
    uv = xy / 40.0 + 0.5
    a = np.radians(20.0)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    want = (uv * 20.0) @ rot.T + [0.3, 0.1]
    assert np.allclose(s.uv[ground], want, atol=1e-4)


def test_mapping_types_texture_is_the_inverse_of_point(bpy_mod):
    from penumbra.engine.blender.extract import _mapping_matrix
    bpy = bpy_mod
    _empty_scene(bpy)
    mat = bpy.data.materials.new("M")
    nodes = mat.node_tree.nodes
    point, texture = nodes.new("ShaderNodeMapping"), nodes.new("ShaderNodeMapping")
    texture.vector_type = "TEXTURE"
    for node in (point, texture):
        node.inputs["Location"].default_value = (0.4, -0.2, 0.0)
        node.inputs["Rotation"].default_value = (0.0, 0.0, 0.7)
        node.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
    assert np.allclose(_mapping_matrix(point) @ _mapping_matrix(texture), np.eye(3), atol=1e-6)
    normal = nodes.new("ShaderNodeMapping")
    normal.vector_type = "NORMAL"
    assert _mapping_matrix(normal) is None


def _drive_base_colour(mat, node_type):
    """A new `node_type` node in `mat` whose Color output drives the Principled BSDF's Base Color."""
    nt = mat.node_tree
    node = nt.nodes.new(node_type)
    bsdf = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    nt.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    return node


def _image_material(bpy, name, image, vector_node=None, output="UV"):
    from penumbra.engine.measure import scenes
    mat = scenes.diffuse_material(name, (1, 1, 1))
    tex = _drive_base_colour(mat, "ShaderNodeTexImage")
    tex.image = image
    if vector_node is not None:
        nt = mat.node_tree
        nt.links.new(vector_node(nt).outputs[output], tex.inputs["Vector"])
    return mat, tex


def test_uv_map_node_texture_coordinate_and_the_active_map(bpy_mod):
    bpy = bpy_mod
    from penumbra.engine.measure import scenes
    _empty_scene(bpy)
    img = scenes.checker_image("C", size=8, cells=2)

    def named(nt):
        node = nt.nodes.new("ShaderNodeUVMap")
        node.uv_map = "Second"
        return node

    cases = {"active": None, "coord": lambda nt: nt.nodes.new("ShaderNodeTexCoord"), "named": named}
    for i, (name, vector) in enumerate(cases.items()):
        ob = _quad_object(bpy, name, _image_material(bpy, name, img, vector)[0], z=0.1 * i)
        scenes.set_planar_uv(ob, scale=2.0)                    # "UVMap", the active one: (x, y) / 2 + 0.5
        second = ob.data.uv_layers.new(name="Second")
        second.uv.foreach_set("vector", np.full(8, 0.25, np.float32))
        ob.data.uv_layers["UVMap"].active_render = True
    s = _snap(bpy)
    names = [o.name for o in s.objects]
    for name in ("active", "coord"):
        sel = s.object_id == names.index(name)
        assert np.allclose(s.uv[sel], s.positions[sel][..., :2] / 2.0 + 0.5, atol=1e-6), name
    assert np.allclose(s.uv[s.object_id == names.index("named")], 0.25)
    assert len(s.textures) == 1                                # one image, one setting: one texture


def test_mirrored_instances_keep_each_corner_its_uv(bpy_mod):
    """Mirrored instances have corners 1 and 2 swapped to keep their winding: their uv must follow."""
    bpy = bpy_mod
    from penumbra.engine.measure import scenes
    _empty_scene(bpy)
    img = scenes.checker_image("C", size=8, cells=2)
    mat, _ = _image_material(bpy, "M", img)
    plain = _quad_object(bpy, "Plain", mat)
    scenes.set_planar_uv(plain, scale=2.0)
    plain.data.vertices[2].co.x = 1.5                           # not symmetric, so a swap would show
    mirrored = bpy.data.objects.new("Mirrored", plain.data)
    bpy.context.scene.collection.objects.link(mirrored)
    mirrored.scale = (-1.0, 1.0, 1.0)
    mirrored.location = (0.0, 0.0, 1.0)
    bpy.context.view_layer.update()
    s = _snap(bpy)
    names = [o.name for o in s.objects]
    for name, ob in (("Plain", plain), ("Mirrored", mirrored)):
        sel = s.object_id == names.index(name)
        inv = np.linalg.inv(np.array(ob.matrix_world))
        world = s.positions[sel].reshape(-1, 3).astype(np.float64)
        local = (world @ inv[:3, :3].T + inv[:3, 3]).reshape(-1, 3, 3)
        # The UV map was made from the original corners (before the 1.5 move): look each corner up by vertex.
        co = np.array([v.co[:] for v in ob.data.vertices])
        vertex = np.argmin(np.linalg.norm(local[..., None, :] - co[None, None], axis=-1), axis=-1)
        original = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
        assert np.allclose(s.uv[sel], original[vertex] / 2.0 + 0.5, atol=1e-6), name


def test_colour_attribute_per_corner_and_point(bpy_mod):
    bpy = bpy_mod
    from penumbra.engine.measure import scenes
    _empty_scene(bpy)
    cases = (("CORNER", "BYTE_COLOR", "ShaderNodeVertexColor"), ("POINT", "FLOAT_COLOR", "ShaderNodeAttribute"))
    for i, (domain, kind, node_type) in enumerate(cases):
        mat = scenes.diffuse_material(f"Col{i}", (1, 1, 1))
        node = _drive_base_colour(mat, node_type)
        if node_type == "ShaderNodeVertexColor":
            node.layer_name = "Paint"
        else:
            node.attribute_name = "Paint"
        ob = _quad_object(bpy, f"Q{i}", mat, z=0.1 * i)
        attr = ob.data.color_attributes.new("Paint", kind, domain)
        colours = np.array([[0.1, 0.2, 0.3, 1], [0.4, 0.5, 0.6, 1], [0.7, 0.8, 0.9, 1], [1.0, 0.5, 0.0, 1]],
                           np.float32)
        attr.data.foreach_set("color", colours.ravel())
    s = _snap(bpy)
    assert not s.warnings, s.warnings
    assert s.texture_id is None and s.corner_color is not None
    names = [o.name for o in s.objects]
    for i in range(2):
        sel = s.object_id == names.index(f"Q{i}")
        # Each corner's colour is that of the quad corner it sits on (corners and points coincide here).
        corner = np.rint((s.positions[sel][..., 0] + 1) / 2 + 2 * (s.positions[sel][..., 1] + 1) / 2).astype(int)
        order = np.array([0, 1, 3, 2])                        # (x, y) bits → quad corner index
        want = colours[order[corner], :3]
        assert np.allclose(s.corner_color[sel], want, atol=5e-3), i   # bytes round-trip through sRGB


def test_what_is_not_read_is_named_and_grey(bpy_mod):
    bpy = bpy_mod
    from penumbra.engine.measure import scenes
    _empty_scene(bpy)
    noise = scenes.diffuse_material("Noisy", (1, 1, 1))
    _drive_base_colour(noise, "ShaderNodeTexNoise").name = "My Noise"
    _quad_object(bpy, "A", noise)
    img = scenes.checker_image("C", size=8, cells=2)
    generated, _ = _image_material(bpy, "Generated", img, lambda nt: nt.nodes.new("ShaderNodeTexCoord"),
                                   output="Generated")
    _quad_object(bpy, "B", generated, z=0.1)
    no_uv, _ = _image_material(bpy, "NoUV", img)
    _quad_object(bpy, "C", no_uv, z=0.2)                       # a mesh without any UV map
    missing = bpy.data.images.new("Missing", 4, 4)
    missing.source, missing.filepath = "FILE", "/nonexistent/missing.png"
    lost, _ = _image_material(bpy, "Lost", missing)
    _quad_object(bpy, "D", lost, z=0.3)
    s = _snap(bpy)
    text = "\n".join(s.warnings)
    assert "material 'Lost'" in text and "image 'Missing' which has no pixels" in text
    assert "material 'Noisy'" in text and "'My Noise' (ShaderNodeTexNoise)" in text and "0.8 grey" in text
    assert "material 'Generated'" in text and "Generated output" in text
    assert "object 'C' has no UV map" in text
    names = [o.name for o in s.objects]
    assert np.allclose(s.albedo[s.object_id == names.index("A")], 0.8)
    assert np.allclose(s.albedo[s.object_id == names.index("B")], 0.8)
    assert np.allclose(s.albedo[s.object_id == names.index("D")], 0.8)
    assert (s.texture_id[s.object_id == names.index("C")] == 0).all()   # read at (0, 0), as warned
    assert np.allclose(s.uv[s.object_id == names.index("C")], 0.0)


def test_linear_and_float_images_are_not_decoded(bpy_mod):
    bpy = bpy_mod
    from penumbra.engine.blender.extract import image_rgb
    _empty_scene(bpy)
    values = np.tile(np.array([0.2, 0.4, 0.6, 1.0], np.float32), 4)
    byte = bpy.data.images.new("byte", 2, 2)
    byte.colorspace_settings.name = "Non-Color"
    byte.pixels.foreach_set(values)
    flt = bpy.data.images.new("float", 2, 2, float_buffer=True)
    flt.pixels.foreach_set(values)
    warnings = []
    for img in (byte, flt):
        rgb, encoded = image_rgb(img, warnings.append)
        assert not encoded and rgb.dtype == np.float32
        assert np.allclose(rgb, [0.2, 0.4, 0.6], atol=2.5e-3), img.name
    assert not warnings


# ----------------------------------------------------------------------------------------------------------
# The textured built-in scene against Cycles
# ----------------------------------------------------------------------------------------------------------

def _paint_ground(bpy, scene):
    """The textured scene's ground coloured by a corner colour attribute (Color Attribute node) instead."""
    from penumbra.engine.measure import scenes
    ground = scene.objects[scenes.GROUND_NAME]
    mat = scenes.diffuse_material("Painted", (1, 1, 1))
    _drive_base_colour(mat, "ShaderNodeVertexColor").layer_name = "Paint"
    ground.data.materials[0] = mat
    attr = ground.data.color_attributes.new("Paint", "BYTE_COLOR", "CORNER")
    attr.data.foreach_set("color", np.array([[0.9, 0.1, 0.1, 1], [0.1, 0.9, 0.1, 1], [0.1, 0.1, 0.9, 1],
                                             [0.9, 0.9, 0.1, 1]], np.float32).ravel())
    bpy.context.view_layer.update()


# Measured at 64², 256 spp (mean |P - C| / mean C), unshadowed pixels / every pixel: image 0.0010 / 0.0059,
# attribute 0.0006 / 0.0059. Cycles' own noise (seed 0 against seed 1) is 0.0018 on the image scene; REFERENCE's
# shadow error makes up the rest of the second figure. The bounds (0.004, 0.015) leave room for that noise.
@pytest.mark.parametrize("case", ["image", "attribute"])
def test_textured_scene_combined_matches_cycles(bpy_mod, case):
    """Penumbra's Combined (REFERENCE visibility) against Cycles' Combined with the scene's own materials: the
    checker image through UV Map → Mapping, or a colour attribute. Before textures were read the ground was 0.8
    grey: 0.99 over every pixel."""
    bpy = bpy_mod
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.measure import reference, scenes
    n = 64
    scene = scenes.build("textured", resolution=(n, n))
    if case == "attribute":
        _paint_ground(bpy, scene)
    cycles = reference.cycles_combined(scene, samples=256, seed=0, width=n, height=n)
    ref = reference.cycles_visibility(scene, samples=256, width=n, height=n)
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert not snap.warnings, snap.warnings
    # Cycles' reference here is point-filtered (one ray per pixel centre); anti-aliasing would box-filter the
    # checker over each pixel's samples (measured 0.011 on the lit ground), so it is compared off.
    result = pipeline.render(snap, RenderSettings(technique="REFERENCE", antialiasing=False))
    ours = result.passes["Combined"][..., :3]
    vis = result.passes["Visibility"].reshape(n, n)
    lit = (ref.visibility > 0.999) & (vis > 0.999)
    assert lit.sum() > 0.4 * n * n
    err = np.abs(ours - cycles).mean(-1)
    lit_err, all_err = err[lit].mean() / cycles[lit].mean(), err.mean() / cycles.mean()
    print(f"{case}: lit mean rel {lit_err:.4f} over {lit.sum()} px, all pixels {all_err:.4f}")
    assert lit_err < 0.004, lit_err
    assert all_err < 0.015, all_err
    lum = ours[lit].mean(-1)
    if case == "image":
        # The checker is there: the lit ground's pixels split into bright and dark squares, as in Cycles.
        assert np.percentile(lum, 90) > 10.0 * np.percentile(lum, 10)
    else:
        # Not grey: the corner colours give the lit ground a hue that changes across the image.
        hue = ours[lit][:, 0] / np.maximum(ours[lit][:, 2], 1e-6)
        assert np.percentile(hue, 95) > 1.2 * np.percentile(hue, 5)


class _Labels:
    """Stands in for Blender's UILayout and records the labels a panel draws."""

    def __init__(self):
        self.lines = []

    def column(self, **_):
        return self

    def label(self, text="", icon="NONE"):
        self.lines.append((icon, text))


def test_material_panel_says_what_is_read_and_what_is_not(bpy_mod):
    bpy = bpy_mod
    import penumbra
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    from penumbra.engine.measure import scenes
    from penumbra.ui.panels import MATERIAL_PT_penumbra
    scenes.build("textured", resolution=(32, 32))
    assert hasattr(bpy.types, "MATERIAL_PT_penumbra")
    icons = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())

    def drawn(mat):
        layout = _Labels()
        MATERIAL_PT_penumbra.draw(type("Panel", (), {"layout": layout})(), type("Ctx", (), {"material": mat})())
        assert all(icon in icons for icon, _ in layout.lines)
        return layout.lines

    checker = drawn(bpy.data.materials["CheckerMaterial"])
    assert checker[0][1] == "Base colour: image 'Checker' through the active UV map and a Mapping"
    assert not any(icon == "ERROR" for icon, _ in checker)
    noisy = bpy.data.materials["OccluderMaterial"].copy()
    _drive_base_colour(noisy, "ShaderNodeTexWave")
    lines = drawn(noisy)
    assert lines[0][1] == "Base colour: 0.8 grey"
    errors = " ".join(text for icon, text in lines if icon in ("ERROR", "BLANK1"))
    assert lines[1][0] == "ERROR" and "Wave Texture" in errors and "does not read" in errors


@pytest.mark.parametrize("case", ["image", "attribute"])
def test_viewport_frame_matches_the_final_render_when_textured(bpy_mod, case):
    bpy = bpy_mod
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.blender.viewport_sync import BlenderViewport
    from penumbra.engine.measure import scenes
    scene = scenes.build("textured", resolution=(64, 48))
    if case == "attribute":
        _paint_ground(bpy, scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, scene)
    settings = RenderSettings(technique="PCSS", shadow_map_size=256)
    final = pipeline.render(snap, settings)
    session = BlenderViewport()
    try:
        session.sync(depsgraph)
        session.request(snap.camera, settings, progressive=False)
        frame = session.wait()
    finally:
        session.free()
    diff = np.abs(frame.passes["Unshadowed"] - final.passes["Unshadowed"])
    # Object-space buffers transformed on the GPU vs world-space vertices in numpy: float rounding only.
    assert np.mean(diff) < 1e-3 * np.mean(final.passes["Unshadowed"]) + 1e-4, np.mean(diff)
    assert np.mean(diff > 1e-2) < 0.01
