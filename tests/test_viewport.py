"""The interactive viewport without a window: same image as the final render, incremental uploads,
progressive frames, cancellation of stale work."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.render import pipeline  # noqa: E402
from penumbra.engine.measure import scenes
from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.blender.viewport_sync import BlenderViewport as ViewportSession, UpdateRecorder  # noqa: E402


@pytest.fixture()
def balls():
    sc = scenes.build("balls", resolution=(96, 72))
    updates = UpdateRecorder()
    yield sc, updates
    updates.close()


def test_viewport_frame_matches_the_final_render(balls):
    sc, _ = balls
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc)
    settings = RenderSettings(technique="PCSS", shadow_map_size=512)
    final = pipeline.render(snap, settings)
    session = ViewportSession()
    session.sync(depsgraph)
    session.request(snap.camera, settings, progressive=False)
    frame = session.wait()
    for name in ("Combined", "Visibility", "Unshadowed"):
        diff = np.abs(frame.passes[name] - final.passes[name])
        # Object-space buffers transformed on the GPU vs world-space vertices transformed in numpy: float32
        # rounding moves a handful of edge texels, nothing more.
        assert np.mean(diff) < 1e-3, (name, np.mean(diff))
        assert np.mean(diff > 1e-3) < 0.01, name
    session.free()


def test_updates_upload_exactly_what_changed(balls):
    sc, updates = balls
    session = ViewportSession()
    session.sync(bpy.context.evaluated_depsgraph_get())
    updates.take()
    first = session.uploads
    assert len(first) == 28 and set(first.values()) == {1}          # 27 balls + the ground

    # moving one object: no mesh is read or uploaded
    reads = session.scene.reads
    bpy.data.objects["Ball.000"].location.x += 0.3
    changed = session.sync(bpy.context.evaluated_depsgraph_get(), updates.take())
    assert changed == set() and session.scene.reads == reads and session.uploads == first

    # editing a light: nothing either
    light = next(o for o in sc.objects if o.type == "LIGHT")
    light.data.energy *= 2.0
    light.location.z += 0.2
    changed = session.sync(bpy.context.evaluated_depsgraph_get(), updates.take())
    assert changed == set() and session.uploads == first
    assert session.state.lights[0].power == pytest.approx(light.data.energy)

    # editing one mesh: that mesh alone
    ground = bpy.data.objects["Ground"]
    ground.data.vertices[0].co.z += 0.01
    ground.data.update()
    changed = session.sync(bpy.context.evaluated_depsgraph_get(), updates.take())
    assert changed == {("Ground", ground.data.name)}
    after = session.uploads
    assert after[("Ground", ground.data.name)] == 2
    assert sum(after.values()) == sum(first.values()) + 1
    session.free()


def test_progressive_then_full_and_stale_work_cancelled(balls):
    sc, _ = balls
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc)
    session = ViewportSession()
    session.sync(depsgraph)
    settings = RenderSettings(technique="REFERENCE", shadow_map_size=512).with_(averaged_light_samples=64)
    session.request(snap.camera, settings)
    # A newer view arrives at once: everything queued or running for the first is dropped.
    moved = snap.camera.view.copy()
    moved[0, 3] += 0.05
    from dataclasses import replace
    session.request(replace(snap.camera, view=moved), settings)
    frame = session.wait()
    assert not frame.coarse and frame.request == 2
    assert frame.width == snap.camera.width
    assert session.cancelled >= 1
    assert session.request(replace(snap.camera, view=moved), settings) is False   # same view: no new work
    session.free()


def test_coarse_frame_uses_each_techniques_cheap_mode_and_never_raises_quality():
    from penumbra.engine.techniques import TECHNIQUES
    from penumbra.engine.render.viewport import coarse_settings
    for identifier, technique in TECHNIQUES.items():
        full = RenderSettings(technique=identifier, shadow_map_size=2048)
        coarse = coarse_settings(full, 256)
        assert coarse.shadow_map_size == 256
        for name, value in technique.coarse.items():
            got = getattr(coarse, name) if name in RenderSettings.field_names() else coarse.option(name)
            assert got == value, (identifier, name)
    low = coarse_settings(RenderSettings(technique="REFERENCE", shadow_map_size=128)
                          .with_(averaged_light_samples=2), 256)
    assert low.option("averaged_light_samples") == 2 and low.shadow_map_size == 128


def test_an_instance_takes_its_instancers_role_in_the_viewport_too():
    """The viewport reads roles like the final render: an instance whose own Shadow Role is Both inherits
    its instancer's (here CASTER, so SSM draws it into the occluder maps only)."""
    import penumbra
    from penumbra.engine.blender.viewport_sync import ViewportScene
    if not hasattr(bpy.types.Object, "penumbra"):
        penumbra.register()
    sc = scenes.build("plane", resolution=(32, 32))
    src = bpy.data.collections.new("RoleSrc")
    mesh = bpy.data.meshes.new("RoleTri")
    mesh.from_pydata([(0, 0, 1), (1, 0, 1), (0, 1, 1)], [], [(0, 1, 2)])
    src.objects.link(bpy.data.objects.new("RoleTri", mesh))
    instancer = bpy.data.objects.new("RoleInstancer", None)
    instancer.instance_type, instancer.instance_collection = "COLLECTION", src
    instancer.penumbra.role = "CASTER"
    sc.collection.objects.link(instancer)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    final = {(o.name, o.role) for o in extract(depsgraph, sc).objects}
    state, _ = ViewportScene().sync(depsgraph)
    viewport = {(o.name, o.role) for o in state.objects}
    assert ("RoleTri", "CASTER") in final
    assert viewport == final


@pytest.mark.heavy
@pytest.mark.parametrize("technique", ["PCSS", "BACKPROJECTION", "REFERENCE", "SSM"])
def test_a_viewport_redraw_allocates_no_gpu_memory(balls, technique, monkeypatch):
    """Textures, depth textures, framebuffers and buffers come from the worker's pool (gpu/pool.py). Orbiting
    back and forth between two views, once each has been drawn, creates none of them.

    A first move may: a pixel that crosses a horizon gives a light another view, a window whose shorter
    side rounds to another number of texels another map shape (lightview._map_shape). Whether a move this
    small does turns on float rounding (it did on CI, where the balls' corner order, then different in every
    run, gave other normals in their last bits), so both views are drawn once before counting."""
    import moderngl
    from dataclasses import replace
    sc, _ = balls
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc)
    settings = RenderSettings(technique=technique, shadow_map_size=256).with_(averaged_light_samples=8)
    session = ViewportSession()
    session.sync(depsgraph)
    moved = snap.camera.view.copy()
    moved[0, 3] += 1e-4
    cameras = [snap.camera, replace(snap.camera, view=moved)]

    def draw(request: int):
        session.request(cameras[request % 2], settings, progressive=False)
        frame = session.wait(timeout=900.0)   # a loaded machine takes minutes: the test is about memory
        assert frame.request == request + 1 and not frame.coarse

    draw(0)
    draw(1)
    created = []
    for kind in ("texture", "depth_texture", "texture_array", "framebuffer", "buffer"):
        original = getattr(moderngl.Context, kind)
        monkeypatch.setattr(moderngl.Context, kind,
                            lambda self, *a, _k=kind, _f=original, **kw: (created.append(_k), _f(self, *a, **kw))[1])
    draw(2)
    draw(3)
    assert created == [], f"{technique}: a redraw created {created}"
    session.free()


@pytest.mark.parametrize("name", ["tilted", "room"])
def test_the_viewport_leaves_out_what_the_final_render_does(name):
    """The final render leaves floors, rooms and convex casters out of the light views that need not hold
    them (SceneSnapshot.flat_objects, convex_objects, convex_casters). The viewport read none of these (its
    meshes live in object space on the GPU) and built every view the final render leaves out: on `tilted`
    at 96² (HARD) 6 views against 3, on `room` 6 against 1. It now reads them from its instances in world
    space, once per sync: the same views, the same image."""
    sc = scenes.build(name, resolution=(96, 96))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    snap = extract(depsgraph, sc)
    settings = RenderSettings(technique="HARD", antialiasing=False)
    final = pipeline.render(snap, settings)
    session = ViewportSession()
    session.sync(depsgraph)
    session.request(snap.camera, settings, progressive=False)
    frame = session.wait(timeout=900.0)
    session.free()
    assert frame.stats["views"] == final.stats["views"]
    assert frame.stats["lights_unshadowed"] == final.stats["lights_unshadowed"]
    diff = np.abs(frame.passes["Visibility"] - final.passes["Visibility"])
    assert np.mean(diff > 1e-3) < 0.01, float(np.mean(diff > 1e-3))


def test_a_coarse_frame_leaves_working_out_the_culling_facts_to_the_full_one():
    """After a sync (an object dragged) the facts are forgotten; a coarse frame takes the ones known, else
    none, and does not build the world-space snapshot they are read from (a few hundred ms on city)."""
    from penumbra.engine.gpu.geometry import SceneGeometry
    from penumbra.tests.synthetic import quad
    from penumbra.engine.core.snapshot import ObjectInfo, SceneSnapshot
    floor = quad((0.0, 0.0, 1.0), 2.0)
    built = []

    class Geometry(SceneGeometry):
        def culling_snapshot(self):
            built.append(1)
            return SceneSnapshot(floor, np.zeros_like(floor), np.zeros(len(floor), np.int32),
                                 np.zeros((len(floor), 3), np.float32), [ObjectInfo("Floor")], [], None)
    g = Geometry()
    g.reads_facts = False
    assert g.flat_objects() == {} and built == []
    g.reads_facts = True
    assert 0 in g.flat_objects() and built == [1]
    g.reads_facts = False
    assert 0 in g.flat_objects() and built == [1]          # known already: taken
    g.forget_facts()
    assert g.flat_objects() == {} and built == [1]
