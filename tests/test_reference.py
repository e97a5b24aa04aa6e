"""engine.measure.reference: Cycles visibility on a small analytic scene (needs bpy; ~10-20 s).

Scene: ground plane z=0, a 1x1 occluder at (0.5, 0.5, 1) hidden from the camera (so the camera sees
the shadow on the ground through it), a 1x1 square area light at (0, 0, 3) facing down, and an
orthographic camera looking straight down covering [-2, 2]^2, 64x64 pixels.
"""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import metrics as M  # noqa: E402
from penumbra.engine.measure import reference as R  # noqa: E402

RES = 64
SPP = 64


def build_scene(res=RES):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=10, location=(0, 0, 0))
    bpy.context.object.name = "Ground"
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0.5, 0.5, 1))
    occ = bpy.context.object
    occ.name = "Occluder"
    occ.visible_camera = False
    light = bpy.data.lights.new("Area", "AREA")
    light.shape = "SQUARE"
    light.size = 1.0
    light.energy = 200.0
    lo = bpy.data.objects.new("Area", light)
    lo.location = (0, 0, 3)
    scene.collection.objects.link(lo)
    cam = bpy.data.cameras.new("Cam")
    cam.type = "ORTHO"
    cam.ortho_scale = 4.0
    co = bpy.data.objects.new("Cam", cam)
    co.location = (0, 0, 8)
    scene.collection.objects.link(co)
    scene.camera = co
    scene.render.resolution_x = scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    return scene


def analytic_visibility(res=RES, n=64):
    """Irradiance-weighted visibility at each pixel centre by quadrature over the light (n x n points):
    V = 1 - sum_blocked w / sum w with w = cos * cos / r^2 = 9 / r^4 (light 3 above the ground).
    Row 0 = bottom (y = -2)."""
    c = (np.arange(res) + 0.5) / res * 4.0 - 2.0
    X, Y = np.meshgrid(c, c)
    g = (np.arange(n) + 0.5) / n - 0.5
    LX, LY = np.meshgrid(g, g)
    light = np.stack([LX.ravel(), LY.ravel()], 1)[None]
    pts = np.stack([X.ravel(), Y.ravel()], 1)
    out = np.empty(len(pts))
    for i in range(0, len(pts), 512):
        p = pts[i:i + 512, None, :]
        d = light - p
        w = 1.0 / ((d ** 2).sum(-1) + 9.0) ** 2
        q = p + d / 3.0  # where the ray to the light crosses the occluder plane z = 1
        blocked = (np.abs(q[..., 0] - 0.5) <= 0.5) & (np.abs(q[..., 1] - 0.5) <= 0.5)
        out[i:i + 512] = 1.0 - (w * blocked).sum(1) / w.sum(1)
    return out.reshape(res, res)


def pix(x, y, res=RES):
    """(row, col) of the pixel containing world point (x, y) on the ground; row 0 = bottom."""
    return int((y + 2.0) / 4.0 * res), int((x + 2.0) / 4.0 * res)


def settings_snapshot(scene):
    cy, r = scene.cycles, scene.render
    return dict(
        engine=r.engine, samples=cy.samples, seed=cy.seed, bounces=cy.max_bounces,
        denoise=cy.use_denoising, adaptive=cy.use_adaptive_sampling, filter=cy.pixel_filter_type,
        width=cy.filter_width, world=scene.world, media=r.image_settings.media_type,
        fmt=r.image_settings.file_format, filepath=r.filepath, res=(r.resolution_x, r.resolution_y),
        overrides=[vl.material_override for vl in scene.view_layers],
        shadow={o.name: o.visible_shadow for o in scene.objects},
        camera_vis={o.name: o.visible_camera for o in scene.objects},
        materials=len(bpy.data.materials), worlds=len(bpy.data.worlds),
    )


@pytest.fixture(scope="module")
def scene():
    return build_scene()


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("refcache")


@pytest.fixture(scope="module")
def ref(scene, cache):
    before = settings_snapshot(scene)
    res = R.cycles_visibility(scene, samples=SPP, seed=0, cache_dir=cache)
    assert settings_snapshot(scene) == before
    return res


def test_shapes_and_types(ref):
    assert ref.visibility.shape == (RES, RES) and ref.visibility.dtype == np.float32
    assert ref.mask.shape == (RES, RES) and ref.mask.dtype == bool
    assert ref.shadowed.shape == ref.unshadowed.shape == (RES, RES, 3)
    assert ref.samples == SPP and ref.seed == 0 and ref.seconds > 0 and not ref.cached
    assert ref.mask.all()  # every pixel sees the lit ground
    assert np.all((ref.visibility >= 0) & (ref.visibility <= 1))


def test_umbra_penumbra_lit_and_orientation(ref):
    v = ref.visibility
    assert v[pix(0.75, 0.75)] < 0.02           # under the occluder centre: umbra
    assert v[pix(-1.5, -1.5)] > 0.99           # far corner: fully lit
    assert v[pix(-1.5, 1.5)] > 0.99
    # umbra is x, y in [0.25, 1.25]; penumbra out to -0.25 and 1.75; x = 1.5 sees half the light
    assert 0.3 < v[pix(1.5, 0.75)] < 0.7
    # row 0 is the bottom: the shadow (at +x, +y) sits in the top-right of the array
    assert v[pix(0.75, -0.75)] > 0.99          # the mirror image below is lit


def test_matches_quadrature(ref):
    r = M.compare(ref.visibility, analytic_visibility(), ref.mask)
    assert r["n_shadow"] > 500
    assert r["mae_shadow"] < 0.015, r
    assert r["pixel_match"] > 0.995, r


def test_cache_hit_skips_rendering(scene, cache, ref):
    n = R.render_count
    again = R.cycles_visibility(scene, samples=SPP, seed=0, cache_dir=cache)
    assert R.render_count == n and again.cached and again.key == ref.key
    np.testing.assert_array_equal(again.visibility, ref.visibility)
    np.testing.assert_array_equal(again.shadowed, ref.shadowed)
    np.testing.assert_array_equal(again.unshadowed, ref.unshadowed)
    # the mask threshold is applied after loading: no re-render either
    R.cycles_visibility(scene, samples=SPP, seed=0, cache_dir=cache, threshold=0.5)
    assert R.render_count == n


def test_cache_key_tracks_scene_content(scene, ref):
    kw = dict(samples=SPP, seed=0, width=RES, height=RES, filter_width=R.POINT_FILTER_WIDTH)
    assert R.scene_key(scene, **kw) == ref.key
    occ = bpy.data.objects["Occluder"]
    light = bpy.data.lights["Area"]

    def changed(obj, attr, value):
        old = getattr(obj, attr)
        old = tuple(old) if hasattr(old, "__len__") else old
        setattr(obj, attr, value)
        try:
            return R.scene_key(scene, **kw) != ref.key
        finally:
            setattr(obj, attr, old)

    assert changed(occ, "location", (0.51, 0.5, 1.0))          # object matrix
    assert changed(occ.data.vertices[0], "co", (-0.5, -0.5, 0.01))  # geometry
    assert changed(light, "size", 1.5)                          # light data
    assert changed(bpy.data.objects["Area"], "location", (0, 0, 3.1))
    assert changed(occ, "visible_shadow", False)                # shadow flags
    assert changed(bpy.data.cameras["Cam"], "ortho_scale", 4.5)  # camera
    assert R.scene_key(scene, **{**kw, "seed": 1}) != ref.key
    assert R.scene_key(scene, **kw) == ref.key


def test_settings_restored_after_error(scene, cache, monkeypatch):
    bpy.data.objects["Area"].visible_camera = True  # the reference hides it; it must come back
    before = settings_snapshot(scene)

    def boom(*a, **k):
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(R, "read_exr_combined", boom)
    with pytest.raises(RuntimeError, match="simulated"):
        R.cycles_visibility(scene, samples=4, seed=7, cache_dir=cache)
    assert settings_snapshot(scene) == before
    bpy.data.objects["Area"].visible_camera = False


def test_noise_floor_small_but_nonzero(scene, cache, ref):
    nf = R.noise_floor(scene, SPP, cache_dir=cache)
    assert nf["n_shadow"] > 500
    assert 0.0 < nf["mae_shadow"] < 0.02, nf
    assert nf["pixel_match"] > 0.99


def _add_lamp(scene, radius):
    """A second light beside the square one: a 100 W point light of `radius` at (-1, 1, 2); (data, object)."""
    data = bpy.data.lights.new("Lamp", "POINT")
    data.energy = 100.0
    data.shadow_soft_size = radius
    lamp = bpy.data.objects.new("Lamp", data)
    lamp.location = (-1.0, 1.0, 2.0)
    scene.collection.objects.link(lamp)
    return data, lamp


def test_several_lights_are_rendered_one_at_a_time_and_summed(scene, cache):
    """With a second light the reference renders each light alone (the other hidden) and sums them: Cycles is
    deterministic for a seed, so the sum equals the two one-light references exactly. The lights come back
    as they were, and the key tells it from a render of both at once (one light's key is the same either
    way: test_cache_key_tracks_scene_content)."""
    data, lamp = _add_lamp(scene, 0.2)
    area = bpy.data.objects["Area"]
    more = []
    try:
        kw = dict(samples=16, seed=0, width=32, height=32, cache_dir=cache)
        n = R.render_count
        both = R.cycles_visibility(scene, **kw)
        assert R.render_count == n + 4
        assert not lamp.hide_render and not area.hide_render
        alone = []
        for hidden in (lamp, area):
            hidden.hide_render = True
            alone.append(R.cycles_visibility(scene, **kw))
            hidden.hide_render = False
        for image in ("shadowed", "unshadowed"):
            np.testing.assert_allclose(getattr(both, image), getattr(alone[0], image) + getattr(alone[1], image),
                                       rtol=1e-5, atol=1e-7)
        assert both.mask.sum() > alone[0].mask.sum() // 2
        at_once = R.cycles_visibility(scene, **kw, per_light=False)
        assert at_once.key != both.key
        assert M.compare(at_once.visibility, both.visibility, both.mask)["mae_shadow"] < 0.1
        # past PER_LIGHT_MAX lights the scene's own render is kept (each light's costs about as much)
        for i in range(R.PER_LIGHT_MAX - 1):
            more.append(bpy.data.objects.new(f"Lamp{i}", data))
            scene.collection.objects.link(more[-1])
        key = dict(samples=16, seed=0, width=32, height=32, filter_width=R.POINT_FILTER_WIDTH)
        assert R.scene_key(scene, **key, per_light=True) == R.scene_key(scene, **key, per_light=False)
    finally:
        for ob in more:
            bpy.data.objects.remove(ob)
        bpy.data.objects.remove(lamp)
        bpy.data.lights.remove(data)


def test_lights_rendered_alone_are_every_light_that_renders(scene):
    """A light hidden in the viewport still renders, so it is rendered alone too; a light that a collection
    instance repeats cannot be hidden alone, and the lights then render together."""
    data = bpy.data.lights.new("Spare", "POINT")
    lamp = bpy.data.objects.new("Spare", data)
    scene.collection.objects.link(lamp)
    layer = bpy.context.view_layer
    group = bpy.data.collections.new("LightGroup")
    empty = bpy.data.objects.new("LightGroupInstance", None)
    try:
        lamp.hide_set(True)
        assert {ob.name for ob in R._render_lights(scene, layer)} == {"Area", "Spare"}
        lamp.hide_set(False)
        group.objects.link(bpy.data.objects.new("InstancedLamp", data))
        empty.instance_type = "COLLECTION"
        empty.instance_collection = group
        scene.collection.objects.link(empty)
        layer.update()
        assert R._render_lights(scene, layer) == []
    finally:
        for ob in (empty, lamp, *group.objects):
            bpy.data.objects.remove(ob)
        bpy.data.collections.remove(group)
        bpy.data.lights.remove(data)


def test_centre_lights_cast_the_light_centres_hard_shadow(scene, cache):
    """`centre_lights`: the square light shrunk to its centre (0, 0, 3) casts the occluder's hard shadow, the
    square [0, 1]² scaled by 3 / (3 - 1) from the centre: [0, 1.5]² on the ground, umbra inside and lit
    outside with nothing between (the soft reference has its penumbra there). The light comes back as it was."""
    area = bpy.data.objects["Area"].data
    before = settings_snapshot(scene)
    c = R.cycles_visibility(scene, samples=16, seed=0, cache_dir=cache, centre_lights=True)
    assert settings_snapshot(scene) == before and area.size == 1.0
    assert c.key != R.cycles_visibility(scene, samples=16, seed=0, cache_dir=cache).key
    x = (np.arange(RES) + 0.5) / RES * 4.0 - 2.0
    X, Y = np.meshgrid(x, x)
    inside = (X > 0.05) & (X < 1.45) & (Y > 0.05) & (Y < 1.45)
    outside = (X < -0.05) | (X > 1.55) | (Y < -0.05) | (Y > 1.55)
    assert c.mask.all() and inside.sum() > 300
    assert np.all(c.visibility[inside] < 1e-6) and np.all(c.visibility[outside] > 1.0 - 1e-6)
    assert c.centre_unknown is not None and not c.centre_unknown.any()
    soft = R.cycles_visibility(scene, samples=16, seed=0, cache_dir=cache)
    assert soft.centre_unknown is None
    assert np.mean((soft.visibility[outside] > 0.02) & (soft.visibility[outside] < 0.98)) > 0.05   # penumbra


def test_centre_lights_weigh_each_light_by_its_own_light(scene, cache):
    """With two lights, each light's centre visibility is weighted by the light as it is (rendered alone, its
    casters hidden): the result equals the sum of the two one-light centre references, whose unshadowed images
    are the lights' own unshadowed renders, exactly (the same seed and samples)."""
    data, lamp = _add_lamp(scene, 0.3)
    area = bpy.data.objects["Area"]
    try:
        kw = dict(samples=16, seed=0, width=32, height=32, cache_dir=cache)
        both = R.cycles_visibility(scene, **kw, centre_lights=True)
        assert data.shadow_soft_size == pytest.approx(0.3)
        alone, soft = [], []
        for hidden in (lamp, area):
            hidden.hide_render = True
            alone.append(R.cycles_visibility(scene, **kw, centre_lights=True))
            soft.append(R.cycles_visibility(scene, **kw))
            hidden.hide_render = False
        for image in ("shadowed", "unshadowed"):
            np.testing.assert_allclose(getattr(both, image), getattr(alone[0], image) + getattr(alone[1], image),
                                       rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(both.unshadowed, soft[0].unshadowed + soft[1].unshadowed, rtol=1e-5, atol=1e-7)
    finally:
        bpy.data.objects.remove(lamp)
        bpy.data.lights.remove(data)


def test_centre_lights_are_rendered_alone_whatever_their_number(scene, cache):
    """The soft reference renders more than PER_LIGHT_MAX lights together (each light costs a render), but the
    centre reference needs each light's own light to weigh its centre's visibility: three renders per light
    (its light, its centre shadowed and unshadowed), however many there are."""
    added = [_add_lamp(scene, 0.1) for _ in range(R.PER_LIGHT_MAX)]
    try:
        kw = dict(samples=4, seed=0, width=16, height=16, cache_dir=cache)
        n = R.render_count
        R.cycles_visibility(scene, **kw)
        assert R.render_count == n + 2
        R.cycles_visibility(scene, **kw, centre_lights=True)
        assert R.render_count == n + 2 + 3 * (R.PER_LIGHT_MAX + 1)
    finally:
        for data, lamp in added:
            bpy.data.objects.remove(lamp)
            bpy.data.lights.remove(data)


def test_centre_below_the_horizon_leaves_the_centre_shadow_unknown(scene, cache):
    """A 1.2 rad sun whose centre lies 10° below the ground's horizon still lights the ground with the part of
    its disk above it; its centre carries nothing there, so the centre's shadow says nothing: the ground's
    whole share is `centre_unknown`, and `visibility` counts it as shadowed."""
    import math
    area = bpy.data.objects["Area"]
    data = bpy.data.lights.new("LowSun", "SUN")
    data.energy = 3.0
    data.angle = 1.2
    sun = bpy.data.objects.new("LowSun", data)
    sun.rotation_euler = (math.radians(100.0), 0.0, 0.0)     # light travelling 10° upwards
    scene.collection.objects.link(sun)
    area.hide_render = True
    try:
        c = R.cycles_visibility(scene, samples=16, seed=0, width=32, height=32, cache_dir=cache,
                                centre_lights=True)
        assert c.mask.sum() > 900
        assert np.all(c.centre_unknown[c.mask] > 1.0 - 1e-6) and np.all(c.visibility[c.mask] < 1e-6)
    finally:
        area.hide_render = False
        bpy.data.objects.remove(sun)
        bpy.data.lights.remove(data)
