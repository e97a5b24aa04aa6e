"""The built-in scenes: they build, are complete, deterministic, and their shadow is in frame."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import scenes  # noqa: E402

NAMES = list(scenes.SCENES)


def _triangle_count(scene) -> int:
    depsgraph = bpy.context.evaluated_depsgraph_get()
    total = 0
    for obj in scene.objects:
        if obj.type != "MESH":
            continue
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        mesh.calc_loop_triangles()
        total += len(mesh.loop_triangles)
        evaluated.to_mesh_clear()
    return total


def _geometry_fingerprint(scene) -> dict[str, np.ndarray]:
    """World-space evaluated vertex positions per mesh object, plus light and camera matrices."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    for obj in sorted(scene.objects, key=lambda o: o.name):
        m = np.array(obj.matrix_world, dtype=np.float64)
        if obj.type == "MESH":
            evaluated = obj.evaluated_get(depsgraph)
            mesh = evaluated.to_mesh()
            co = np.empty(len(mesh.vertices) * 3, np.float32)
            mesh.vertices.foreach_get("co", co)
            corners = np.empty(len(mesh.loops), np.int32)     # the faces' corners, in their order
            mesh.loops.foreach_get("vertex_index", corners)
            evaluated.to_mesh_clear()
            out[obj.name] = np.concatenate([co.astype(np.float64), m.ravel(), corners.astype(np.float64)])
        else:
            out[obj.name] = m.ravel()
        if obj.type == "LIGHT":
            out[obj.name + ".energy"] = np.array([obj.data.energy])
    return out


def test_list_scenes_matches_registry():
    listed = scenes.list_scenes()
    assert [n for n, _ in listed] == NAMES
    assert {"plane", "suzanne", "balls", "silhouette", "contact", "thin", "city", "grazing",
            "cube", "tilted", "room", "flattened", "slab"} <= set(NAMES)
    for name, desc in listed:
        assert desc and "\n" not in desc, name


def test_unknown_scene_lists_valid_names():
    with pytest.raises(ValueError) as info:
        scenes.build("no-such-scene")
    message = str(info.value)
    assert "no-such-scene" in message
    for name in NAMES:
        assert name in message


@pytest.mark.parametrize("name", NAMES)
def test_scene_is_complete(name):
    scene = scenes.build(name, resolution=(96, 64))
    assert scene == bpy.context.scene
    assert scene.render.resolution_x == 96 and scene.render.resolution_y == 64
    assert scene.render.resolution_percentage == 100
    assert not scene.render.film_transparent
    assert scene.camera is not None and scene.camera.type == "CAMERA"
    lights = [o for o in scene.objects if o.type == "LIGHT"]
    assert any(o.name == scenes.LIGHT_NAME and o.data.energy > 0 for o in lights)
    ground = scene.objects.get(scenes.GROUND_NAME)
    assert ground is not None and ground.type == "MESH"
    occluders = [o for o in scene.objects if o.type == "MESH" and o.name != scenes.GROUND_NAME]
    assert occluders, "no occluder"
    for obj in scene.objects:
        if obj.type == "MESH":
            assert obj.material_slots and obj.material_slots[0].material is not None, obj.name
    world = scene.world
    assert world is None or tuple(world.color) == (0.0, 0.0, 0.0)
    assert _triangle_count(scene) > 0


def test_city_has_200k_triangles():
    scene = scenes.build("city")
    assert _triangle_count(scene) >= 200_000


@pytest.mark.parametrize("name", NAMES)
def test_build_is_deterministic(name):
    """Vertices, face corners and their order: bmesh's primitives order corners by memory address, which
    changed every error's last digits between runs and made the Cycles reference cache miss each time."""
    from penumbra.engine.measure import reference
    keys, prints = [], []
    for _ in range(2):
        scene = scenes.build(name, resolution=(32, 32))
        prints.append(_geometry_fingerprint(scene))
        keys.append(reference.scene_key(scene, samples=16, seed=0, width=32, height=32, filter_width=1.0))
    first, second = prints
    assert first.keys() == second.keys()
    for key in first:
        np.testing.assert_array_equal(first[key], second[key], err_msg=f"{name}: {key}")
    assert keys[0] == keys[1], f"{name}: the Cycles reference cache key changed between two builds"


def _render_ground_only(scene, path) -> np.ndarray:
    """Cycles render (direct light only) with every occluder hidden from the camera, so each pixel is
    the ground; occluders still cast shadows. Returns linear luminance, shape (H, W)."""
    for obj in scene.objects:
        if obj.type == "MESH" and obj.name != scenes.GROUND_NAME:
            obj.visible_camera = False
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.max_bounces = 0
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    try:
        w, h = image.size
        rgba = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(rgba)
    finally:
        bpy.data.images.remove(image)
    rgb = rgba.reshape(h, w, 4)[..., :3]
    return rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)


@pytest.mark.parametrize("name", NAMES)
def test_cycles_render_shows_lit_ground_and_shadow(name, tmp_path):
    scene = scenes.build(name, resolution=(64, 64))
    lum = _render_ground_only(scene, tmp_path / f"{name}.exr")
    assert lum.shape == (64, 64)
    lit = float(np.percentile(lum, 95))
    # Lit ground radiance of order 0.5-1 (albedo 0.8); city streets are mostly shadowed, hence the margin.
    assert 0.25 < lit < 2.0, f"{name}: lit ground radiance {lit:.3f}"
    # The shadow is in frame: a good share of ground pixels notably darker than the lit ground.
    dark = float(np.mean(lum < 0.75 * lit))
    assert dark > 0.05, f"{name}: only {dark:.1%} of pixels in shadow"
