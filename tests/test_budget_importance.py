"""BACKPROJECTION's budget map from an importance source (Schwarz & Stamminger 2008, §4.2): an image's grey
value and/or the objects' Shadow Importance take each pixel's budget from bp_budget_low to bp_budget. bpy-free
snapshots at small sizes; the levels come from the BP Level debug pass (one integer level per pixel)."""
from dataclasses import replace

import numpy as np
import pytest

from penumbra.engine.core import exr
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.measure import stress
from penumbra.engine.render import pipeline

SIZE = 40
LOW, HIGH = 3, 16


def settings(**options) -> RenderSettings:
    return RenderSettings(technique="BACKPROJECTION", shadow_map_size=256, debug_passes=True).with_(
        **{"bp_blend": False, "bp_budget": HIGH, "bp_budget_low": LOW, **options})


@pytest.fixture(scope="module")
def scene():
    return replace(stress.plane_scene(light_size=1.5, name="importance"), camera=stress.camera(size=SIZE))


def levels(snap, s):
    """(level, backprojected) per pixel, row 0 at the bottom."""
    p = pipeline.render(snap, s).passes
    bp = p["BP Class"][..., 2] > 0.5
    return p["BP Level"][..., 0], bp


@pytest.fixture(scope="module")
def uniform_levels(scene):
    high, bp_high = levels(scene, settings())
    low, bp_low = levels(scene, settings(bp_budget=LOW))
    bp = bp_high & bp_low
    assert bp.sum() > 100 and (low[bp] > high[bp]).sum() > 50      # the budgets are told apart
    return high, low, bp


def test_budget_image_sets_each_pixels_budget(scene, uniform_levels):
    """Bottom half of the image white, top half black: the bottom rows gather at b = 16's levels, the top
    rows at the low budget's; the same whether the image comes read (snapshot) or as a PNG file (files store
    the top row first)."""
    high, low, bp = uniform_levels
    mask = np.zeros((8, 8), np.float32)
    mask[:4] = 1.0                      # row 0 at the bottom
    snap = replace(scene, images={"mask": mask})
    lv, _ = levels(snap, settings(bp_budget_map="IMPORTANCE", bp_budget_image="mask"))
    rows = np.arange(SIZE)[:, None]
    bottom, top = bp & (rows < SIZE // 2 - 3), bp & (rows >= SIZE // 2 + 3)
    assert bottom.sum() > 20 and top.sum() > 20
    assert np.array_equal(lv[bottom], high[bottom]) and np.array_equal(lv[top], low[top])
    assert (low[bottom] > high[bottom]).sum() > 10          # …where the two budgets differ


def test_budget_image_from_a_file_matches_the_read_image(scene, tmp_path):
    mask = np.zeros((8, 8), np.float32)
    mask[:4] = 1.0
    path = tmp_path / "mask.png"
    exr.write_png(str(path), np.repeat((np.flipud(mask) * 255).astype(np.uint8)[..., None], 3, axis=-1))
    from_file, _ = levels(scene, settings(bp_budget_map="IMPORTANCE", bp_budget_image=str(path)))
    read, _ = levels(replace(scene, images={"m": mask}), settings(bp_budget_map="IMPORTANCE",
                                                                  bp_budget_image="m"))
    assert np.array_equal(from_file, read)


def test_object_importance_raises_the_budget_on_its_pixels(scene, uniform_levels):
    """Ground with importance 1, occluder 0: ground pixels gather at b = 16's (finer) levels, the occluder's
    own pixels at the low budget's; with no source at all every pixel has the low budget."""
    high, low, bp = uniform_levels
    names = [o.name for o in scene.objects]
    objects = [replace(o, importance=1.0 if o.name == "Ground" else 0.0) for o in scene.objects]
    snap = replace(scene, objects=objects)
    lv, _ = levels(snap, settings(bp_budget_map="IMPORTANCE"))
    none, _ = levels(scene, settings(bp_budget_map="IMPORTANCE"))
    assert np.array_equal(none[bp], low[bp])
    # The ground's pixels: where b = 16 and the low budget differ, the importance map follows b = 16.
    ground = bp & (lv == high)
    assert "Ground" in names and (ground & (low > high)).sum() > 50
    assert lv[bp].mean() < none[bp].mean()                       # higher budget → finer levels
    assert np.all((lv[bp] == high[bp]) | (lv[bp] == low[bp]))


def test_missing_budget_image_is_one_line_naming_the_setting(scene):
    with pytest.raises(ValueError) as err:
        pipeline.render(scene, settings(bp_budget_map="IMPORTANCE", bp_budget_image="no_such_mask"))
    message = str(err.value)
    assert "bp_budget_image" in message and "no_such_mask" in message and "\n" not in message


def test_extraction_reads_object_importance_and_the_named_blender_image():
    """Blender side: an object's Shadow Importance (or its custom property penumbra_importance, which wins)
    reaches the snapshot's objects; the budget image named in the scene settings, or in RenderSettings given
    to the extraction (the command line's --set), is read as a datablock's grey pixels."""
    bpy = pytest.importorskip("bpy")
    import penumbra
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.blender.settings_bridge import settings_from_scene
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    for name, value, custom in (("Ground", 0.75, None), ("Plate", 0.2, 1.0), ("Other", 0.0, None)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        ob = bpy.data.objects.new(name, mesh)
        sc.collection.objects.link(ob)
        ob.penumbra.importance = value
        if custom is not None:
            ob["penumbra_importance"] = custom
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    sc.collection.objects.link(cam)
    sc.camera = cam
    image = bpy.data.images.new("Mask", 4, 2)
    pixels = np.zeros((2, 4, 4), np.float32)
    pixels[1, :, :3] = 1.0              # top row white (Blender's row 0 is the bottom)
    image.pixels.foreach_set(pixels.ravel())
    sc.penumbra.technique = "BACKPROJECTION"
    sc.penumbra.bp_budget_map = "IMPORTANCE"
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc, width=8, height=8)
    assert {o.name: o.importance for o in snap.objects} == {"Ground": 0.75, "Plate": 1.0, "Other": 0.0}
    assert snap.images == {}            # no image named
    settings = settings_from_scene(sc).with_(bp_budget_image="Mask")
    grey = extract(depsgraph, sc, width=8, height=8, settings=settings).images["Mask"]
    assert np.array_equal(grey, [[0, 0, 0, 0], [1, 1, 1, 1]])
    sc.penumbra.bp_budget_image = "Missing"
    with pytest.raises(ValueError, match="bp_budget_image"):
        extract(depsgraph, sc, width=8, height=8)
