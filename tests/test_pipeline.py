"""The GPU pipeline on scenes built directly as snapshots (no bpy): finite, bounded, and exact where the
geometry has a closed form."""
import numpy as np
import pytest

from penumbra.engine.render import pipeline
from penumbra.engine.gpu import programs
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.techniques import TECHNIQUES

from penumbra.tests.synthetic import floating_plane, quad


def ground_points(snap):
    """World position of each pixel's ray on the ground plane z = 0 (row 0 at the bottom)."""
    cam = snap.camera
    w, h = cam.width, cam.height
    xs = (np.arange(w) + 0.5) / w * 2 - 1
    ys = (np.arange(h) + 0.5) / h * 2 - 1
    ndc = np.stack(np.meshgrid(xs, ys), -1)
    inv = np.linalg.inv(cam.projection @ cam.view)
    near = np.c_[ndc.reshape(-1, 2), -np.ones(w * h), np.ones(w * h)] @ inv.T
    far = np.c_[ndc.reshape(-1, 2), np.ones(w * h), np.ones(w * h)] @ inv.T
    near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
    t = near[:, 2] / (near[:, 2] - far[:, 2])
    return (near + (far - near) * t[:, None]).reshape(h, w, 3)


def exact_area_visibility(points, light_half, occ_half, occ_height, light_height):
    """Unoccluded fraction of a square light seen from ground points past a parallel square occluder:
    the occluder projected from x onto the light plane is a square scaled by k = h_light / h_occluder."""
    k = light_height / occ_height
    centre = points[..., :2] * (1 - k)
    half = occ_half * k
    lo = np.maximum(centre - half, -light_half)
    hi = np.minimum(centre + half, light_half)
    overlap = np.clip(hi - lo, 0, None).prod(axis=-1)
    return 1.0 - overlap / (2 * light_half) ** 2


@pytest.fixture(scope="module")
def scene():
    return floating_plane(96)


@pytest.mark.parametrize("technique", list(TECHNIQUES))
def test_every_technique_is_finite_and_bounded(scene, technique):
    r = pipeline.render(scene, RenderSettings(technique=technique, shadow_map_size=256)
                        .with_(averaged_light_samples=16))
    for name, array in r.passes.items():
        assert np.isfinite(array).all(), f"{technique}: non-finite values in {name}"
    v = r.passes["Visibility"][..., 0]
    assert v.min() >= 0.0 and v.max() <= 1.0
    assert v.min() == 0.0, "the umbra under the occluder must be fully shadowed"
    assert (v == 1.0).mean() > 0.5, "most of the ground is lit"
    assert r.stats["lights_skipped"] == 0


def test_reference_matches_the_closed_form(scene):
    """Unweighted REFERENCE converges to the exact unoccluded light fraction of the parallel-planes case."""
    r = pipeline.render(scene, RenderSettings(technique="REFERENCE", shadow_map_size=1024)
                        .with_(averaged_light_samples=256, averaged_weighted=False))
    pts = ground_points(scene)
    on_ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(scene, pts)) < 1e-3
    exact = exact_area_visibility(pts, 0.5, 0.5, 1.0, 3.0)
    v = r.passes["Visibility"][..., 0]
    err = np.abs(v - exact)[on_ground & (exact < 0.99)]
    assert err.size > 500
    # 256 samples quantise V in steps of 1/256; one texel of a 1024² map moves an edge by ~0.2 pixel here.
    print("REFERENCE vs closed form: mean", err.mean(), "p99", np.percentile(err, 99))
    assert err.mean() < 0.01, err.mean()
    assert np.percentile(err, 99) < 0.06


def _ground_depth(snap, pts):
    hom = np.c_[pts.reshape(-1, 3), np.ones(pts.shape[0] * pts.shape[1])] @ snap.camera.view.T
    return -hom[:, 2].reshape(pts.shape[:2])


def test_pcss_is_close_to_the_closed_form_on_parallel_planes(scene):
    """PCSS's penumbra estimate is exact for parallel planes, so only its sampling error remains."""
    r = pipeline.render(scene, RenderSettings(technique="PCSS", shadow_map_size=1024)
                        .with_(pcss_blocker_samples=64, pcss_filter_samples=256))
    pts = ground_points(scene)
    on_ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(scene, pts)) < 1e-3
    exact = exact_area_visibility(pts, 0.5, 0.5, 1.0, 3.0)
    err = np.abs(r.passes["Visibility"][..., 0] - exact)[on_ground & (exact < 0.99)]
    assert err.mean() < 0.05, err.mean()


def test_light_that_reaches_nothing_is_skipped():
    snap = floating_plane(32)
    snap.lights[0].matrix[:3, 3] = (0.0, 0.0, -5.0)     # below the ground, facing down: reaches nothing
    r = pipeline.render(snap, RenderSettings(technique="HARD"))
    assert r.stats["lights_skipped"] == 1
    assert "shadow_map" not in r.timings
    assert np.all(r.passes["Visibility"] == 1.0)
    assert np.all(r.passes["Combined"][..., :3] == 0.0)


def test_no_lights_gives_black_combined_and_a_warning():
    snap = floating_plane(32)
    snap.lights.clear()
    r = pipeline.render(snap, RenderSettings(technique="PCSS"))
    assert np.all(r.passes["Combined"][..., :3] == 0.0)
    assert np.all(r.passes["Visibility"] == 1.0)
    assert any("no lights" in w for w in r.warnings)


def test_bad_setting_names_the_setting():
    with pytest.raises(ValueError, match="shadow_map_size"):
        pipeline.render(floating_plane(16), RenderSettings(shadow_map_size=3))
    with pytest.raises(ValueError, match="Unknown technique 'NOPE'"):
        pipeline.render(floating_plane(16), RenderSettings(technique="NOPE"))


def test_compile_error_names_file_and_line(tmp_path, monkeypatch):
    (tmp_path / "lib.glsl").write_text("float ok() { return 1.0; }\n")
    (tmp_path / "broken.comp").write_text(
        'layout(local_size_x = 1) in;\n#include "lib.glsl"\nvoid main() {\n    float x = undefined_name;\n}\n')
    monkeypatch.setattr(programs, "GLSL_ROOT", tmp_path)
    from penumbra.engine.gpu.context import GpuWorker
    worker = GpuWorker.get()
    with pytest.raises(programs.ShaderError, match=r"glsl/broken\.comp:4"):
        worker.submit(lambda w: programs.program(w, compute="broken.comp")).result()


def test_zero_size_area_light_emits_nothing():
    """A zero-size area light emits nothing, as in Cycles (tests/test_irradiance_cycles.py renders it black);
    it used to be rendered as a point light with a hard shadow. Every technique: black, V = 1 (unlit)."""
    snap = floating_plane(64, light_size=0.0)
    assert snap.lights[0].is_delta
    for technique in TECHNIQUES:
        r = pipeline.render(snap, RenderSettings(technique=technique).with_(averaged_light_samples=8))
        assert np.all(r.passes["Combined"][..., :3] == 0.0), technique
        assert np.all(r.passes["Unshadowed"] == 0.0), technique
        assert np.all(r.passes["Visibility"] == 1.0), technique


def test_a_stop_request_cancels_the_frame():
    """RenderEngine.test_break reaches the GPU thread: a REFERENCE frame stops between light samples."""
    from penumbra.engine.gpu.context import Cancelled
    calls = []

    def should_stop():
        calls.append(1)
        return True
    with pytest.raises(Cancelled):
        pipeline.render(floating_plane(64), RenderSettings(technique="REFERENCE", shadow_map_size=1024)
                        .with_(averaged_light_samples=4096), should_stop=should_stop)
    assert calls


@pytest.mark.parametrize("facing", ["down", "sideways", "away"])
def test_lit_bounds_on_the_gpu_match_the_irradiance_image(facing):
    """The per-light lit test and receiver box come from a GPU reduction (render/lit_bounds.comp); they must
    equal what the whole irradiance image read back gives: the exact float32 min and max of the lit pixels,
    the count of lit pixels with a direction at or below their horizon (what gates a sun's rim views), and the
    distance from a point to the nearest lit pixel (what places a sphere light's REFERENCE samples)."""
    from penumbra.engine.core.shading import light_defines, light_uniforms
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    snap = floating_plane(48)
    m = snap.lights[0].matrix
    if facing == "sideways":        # emits along +X: only the ground at x > 0 is lit
        m[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]
    elif facing == "away":          # emits straight up: nothing is lit
        m[:3, :3] = np.diag([1.0, -1.0, -1.0])

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            irradiance = frame.texture((frame.width, frame.height), 4)
            light = snap.lights[0]
            frame.dispatch("shading/irradiance.comp", light_uniforms(light), images={0: irradiance},
                           defines=light_defines(light))
            buffer = frame.buffer(bytes(pipeline._BOUNDS_BYTES))
            gpu, none_counted, no_point = pipeline._lit_bounds(frame, irradiance, buffer, centres[0])
            counted = [pipeline._lit_bounds(frame, irradiance, buffer, c, count_hidden=True) for c in centres]
            hidden, nearest = [c[1] for c in counted], [c[2] for c in counted]
            lit = (frame.read(irradiance)[..., 3] > 0) & (frame.read(frame.gbuffer["g_position"])[..., 3] > 0)
            xyz = frame.read(frame.gbuffer["g_position"])[..., :3][lit]
            normals = [frame.read(frame.gbuffer[name])[..., :3][lit] for name in ("g_geometric", "g_normal")]
            return gpu, none_counted, no_point, hidden, nearest, lit, xyz, normals
        finally:
            frame.release()
    # every visible face is horizontal, facing up: straight up is above every horizon, straight down and
    # along the ground are at or below them (directions, w = 0), and so is a point below the ground, while
    # a point between the ground and the plate is above the ground's horizon only (points, w = 1)
    centres = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0],
                        [0.0, 0.0, -2.0, 1.0], [0.0, 0.0, 0.5, 1.0]])
    gpu, none_counted, no_point, hidden, nearest, lit, xyz, (geometric, shading) = \
        GpuWorker.get().submit(job).result()
    assert none_counted == 0 and no_point is None
    if facing == "away":
        assert not lit.any() and gpu is None and hidden == [0] * len(centres)
        return
    expected = []
    for c in centres:
        d = c[:3] - xyz if c[3] else np.broadcast_to(c[:3], xyz.shape)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        expected.append(int(((np.sum(geometric * d, 1) <= 1e-5) & (np.sum(shading * d, 1) <= 1e-5)).sum()))
    assert hidden == expected and expected[0] == 0 and expected[1] == expected[2] == expected[3] == lit.sum()
    assert 0 < expected[4] < lit.sum() or facing == "sideways"
    assert 0 < lit.sum() < lit.size if facing == "sideways" else lit.sum() > 0
    np.testing.assert_array_equal(gpu[0], xyz.min(axis=0).astype(np.float64))
    np.testing.assert_array_equal(gpu[1], xyz.max(axis=0).astype(np.float64))
    for c, d in zip(centres, nearest):     # only points have a nearest pixel
        assert d is None if not c[3] else np.isclose(d, np.linalg.norm(xyz - c[:3], axis=1).min(), rtol=1e-6)


def test_the_gpu_is_synchronised_only_when_stage_times_are_asked(monkeypatch):
    """A normal render waits for the GPU only where it reads a result back; ctx.finish() after every timed
    stage is for the bench's per-stage times (pipeline.render(stage_times=True))."""
    import moderngl
    calls = []
    original = moderngl.Context.finish
    monkeypatch.setattr(moderngl.Context, "finish", lambda self: (calls.append(1), original(self))[1])
    snap = floating_plane(32)
    settings = RenderSettings(technique="REFERENCE").with_(averaged_light_samples=4)
    pipeline.render(snap, settings)
    assert calls == []
    pipeline.render(snap, settings, stage_times=True)
    assert len(calls) > 8           # upload, G-buffer, irradiance, readbacks, 4 × (map, accumulate), …


def test_layered_depth_maps_equal_one_map_per_view():
    """REFERENCE draws a batch of sample maps in one layered pass (Frame.render_depth_layers);
    each layer must hold what a depth map of that view alone holds, also for views of different sizes
    (a smaller map fills its layer's lower-left corner)."""
    from penumbra.engine.core import lightview
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    snap = floating_plane(32)
    light = snap.lights[0]
    receivers = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 0.0]))
    casters = (np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 1.0]))
    views = [lightview.fit(light, receivers, casters, size, origin_local=np.array([x, y, 0.0]))
             for size, x, y in ((128, 0.0, 0.0), (128, 0.4, -0.3), (96, -0.2, 0.5), (64, 0.5, 0.5))]

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            layers = frame.render_depth_layers(views)
            array = np.frombuffer(layers.read(), np.float32).reshape(len(views), layers.height, layers.width)
            single = [frame.read(frame.render_depth_map(v))[..., 0].copy() for v in views]
            return array.copy(), single
        finally:
            frame.release()
    array, single = GpuWorker.get().submit(job).result()
    assert len({m.shape for m in single}) > 1, "the views should differ in size"
    for k, m in enumerate(single):
        h, w = m.shape
        assert (m < 1e9).any(), "the occluder must be in every map"
        np.testing.assert_array_equal(array[k, :h, :w], m)


def test_facet_layers_hold_the_plane_of_the_surface_each_depth_layer_kept():
    """Frame.render_facet_layers (REFERENCE's facet test, averaged_facets): each layer holds, texel for texel,
    the normal of the triangle whose depth its depth layer kept: the plane render_facet_map finds for that view
    alone (up to sign and RGBA16F rounding), (0, 0, 0) where the layer is empty. A ball over the ground,
    its facets facing every way, seen from four points of a tilted light (so that the view frames are not the
    world's)."""
    from penumbra.engine.core import lightview
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    from penumbra.engine.measure import stress
    snap = stress.assemble([("Ground", stress.quad((0, 0, 0), 4.0), True, True),
                            ("Ball", stress.sphere((0.3, -0.2, 1.0), 0.6, rings=8), True, True)],
                           [stress.area_light((2.0, -1.0, 3.0), target=(0.0, 0.0, 0.0), size=1.0)],
                           stress.camera(), "ball")
    receivers = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 0.0]))
    casters = (np.array([-0.3, -0.8, 0.4]), np.array([0.9, 0.4, 1.6]))
    views = [lightview.fit(snap.lights[0], receivers, casters, size, origin_local=np.array([x, y, 0.0]))
             for size, x, y in ((128, 0.0, 0.0), (128, 0.4, -0.3), (96, -0.2, 0.5), (64, 0.5, 0.5))]

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            depths = frame.render_depth_layers(views)
            facets = frame.render_facet_layers(views, depths)
            array = np.frombuffer(facets.read(), np.float16).reshape(len(views), facets.height, facets.width, 4)
            single = [np.frombuffer(t.read(), np.float16).reshape(t.height, t.width, 4)[..., :3].astype(np.float32)
                      for t in (frame.render_facet_map(v) for v in views)]
            return array[..., :3].astype(np.float32), single
        finally:
            frame.release()
    array, single = GpuWorker.get().submit(job).result()
    for k, m in enumerate(single):
        h, w = m.shape[:2]
        layer = array[k, :h, :w]
        known = np.linalg.norm(m, axis=-1) > 0.5
        # the single view's derivatives span each triangle inside it; texels on a triangle's edge may take
        # either neighbour in either pass, so most texels, not all, must agree
        agree = np.abs(np.sum(layer * m, axis=-1)) > 0.999
        assert known.sum() > 1000 and agree[known].mean() > 0.97, agree[known].mean()
        ball = known & (np.abs(m[..., 2]) < 0.99)          # the ball's facets, turned away from the axis
        assert ball.sum() > 100 and agree[ball].mean() > 0.9
    assert np.abs(array).sum(axis=-1).max() > 0.0


def test_peeled_depth_layers_hold_the_surfaces_behind_the_nearest():
    """Frame.render_depth_layers(behind=...) (REFERENCE's soft-falloff samples, SIDE_BEYOND_DISK): each texel
    holds the nearest caster strictly behind the layer given, empty where there is none. Over a plane
    floating above the ground: the plane, then the ground under it (and nothing beside it), then nothing."""
    from penumbra.engine.core import lightview
    from penumbra.engine.core.shader_constants import EMPTY_DEPTH
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    snap = floating_plane(32)
    receivers = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 0.0]))
    casters = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 1.0]))
    views = [lightview.fit(snap.lights[0], receivers, casters, 64, origin_local=np.array([x, 0.0, 0.0]))
             for x in (0.0, 0.3)]

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            first = frame.render_depth_layers(views)
            second = frame.render_depth_layers(views, behind=first)
            third = frame.render_depth_layers(views, behind=second)
            return [np.frombuffer(a.read(), np.float32).reshape(len(views), a.height, a.width).copy()
                    for a in (first, second, third)]
        finally:
            frame.release()
    first, second, third = GpuWorker.get().submit(job).result()
    plane = np.abs(first - 2.0) < 1e-3             # the light is 3 m up, the plane 1 m: depth 2
    ground = np.abs(first - 3.0) < 1e-3            # elsewhere the ground, or nothing past its edge
    assert plane.sum() > 50 and ground.sum() > 1000 and (first[~(plane | ground)] > EMPTY_DEPTH).all()
    np.testing.assert_allclose(second[plane], 3.0, atol=1e-3)
    assert (second[~plane] > EMPTY_DEPTH).all()
    assert (third > EMPTY_DEPTH).all()


def test_casters_outside_a_light_view_are_not_drawn_into_it():
    """Frame.rasterise leaves out objects whose box lies wholly outside the view's clip volume; the map
    is the same as with every object drawn."""
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    from penumbra.engine.core import lightview
    from penumbra.engine.core.snapshot import ObjectInfo
    from dataclasses import replace
    base = floating_plane(32)
    far = quad((30.0, 30.0, 1.0), 0.5)             # a third object far outside the light's view
    snap = replace(base, positions=np.concatenate([base.positions, far]),
                   normals=np.concatenate([base.normals, np.zeros_like(far) + (0, 0, 1)]),
                   object_id=np.concatenate([base.object_id, [2, 2]]).astype(np.int32),
                   albedo=np.concatenate([base.albedo, np.full((2, 3), 0.8, np.float32)]),
                   objects=[*base.objects, ObjectInfo("Far")])
    receivers = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 0.0]))
    view = lightview.fit(snap.lights[0], receivers, (np.array([-0.5, -0.5, 1.0]), np.array([0.5, 0.5, 1.0])), 64)
    drawn = []

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            inside = frame._objects_in_frustum(view.view_proj)
            original = frame.geometry.render
            frame.geometry.render = lambda ctx, prog, role, objects=None, **kw: (drawn.append(objects),
                                                                                 original(ctx, prog, role, objects, **kw))
            culled = frame.read(frame.render_depth_map(view))[..., 0].copy()
            frame.geometry.render = original
            frame._objects_in_frustum = lambda view_proj: None
            full = frame.read(frame.render_depth_map(view))[..., 0].copy()
            return inside, culled, full
        finally:
            frame.release()
    inside, culled, full = GpuWorker.get().submit(job).result()
    assert inside == frozenset({0, 1}) and drawn == [frozenset({0, 1})]
    np.testing.assert_array_equal(culled, full)
    assert (culled < 1e9).any()


def _low_poly_sphere(radius: float, smooth: bool):
    """An octahedron subdivided twice and pushed onto a sphere (128 triangles): radial corner normals when
    `smooth`, each triangle's own when flat."""
    v = np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    faces = [(0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4), (1, 0, 5), (2, 1, 5), (3, 2, 5), (0, 3, 5)]
    tris = np.array([[v[a], v[b], v[c]] for a, b, c in faces])
    for _ in range(2):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tris = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    tris = tris / np.linalg.norm(tris, axis=-1, keepdims=True)
    if smooth:
        normals = tris.copy()
    else:
        n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        normals = np.repeat((n / np.linalg.norm(n, axis=1, keepdims=True))[:, None], 3, axis=1)
    return (radius * tris).astype(np.float32), normals.astype(np.float32)


@pytest.mark.parametrize("smooth", [True, False], ids=["smooth", "flat"])
def test_terminator_lift_moves_a_low_poly_sphere_towards_its_smooth_surface(smooth):
    """The G-buffer's shadow-terminator lift (common/gbuffer.frag, Cycles' smooth-surface offset): on a
    smooth low-poly sphere, the lifted point P + lift·n lies nearer the sphere the corner normals describe
    than the flat triangle's point does, for every pixel off the triangles' edges; flat triangles get none."""
    from penumbra.engine.core.snapshot import Camera, ObjectInfo, SceneSnapshot
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    from penumbra.engine.measure.stress import look_at, perspective
    positions, normals = _low_poly_sphere(1.0, smooth)
    base = floating_plane(64)
    cam = Camera("Camera", np.linalg.inv(look_at((0.3, -3.0, 1.2), (0.0, 0.0, 0.0))),
                 perspective(np.radians(45), 1.0, 0.1, 100.0), 64, 64)
    snap = SceneSnapshot(positions, normals, np.zeros(len(positions), np.int32), np.full((len(positions), 3), 0.8,
                         np.float32), [ObjectInfo("Ball")], base.lights, cam, name="ball")

    def job(worker):
        frame = Frame(worker, snap, RenderSettings().with_(antialiasing=False))
        try:
            return {k: frame.read(t) for k, t in frame.gbuffer.items()}
        finally:
            frame.release()
    g = GpuWorker.get().submit(job).result()
    covered = g["g_position"][..., 3] > 0
    p = g["g_position"][..., :3][covered].astype(np.float64)
    lift = g["g_geometric"][..., 3][covered].astype(np.float64)
    lifted = p + lift[:, None] * g["g_normal"][..., :3][covered]
    assert covered.sum() > 1500
    if not smooth:
        assert np.all(lift == 0.0)
        return
    before = 1.0 - np.linalg.norm(p, axis=1)           # the flat triangles lie inside the sphere
    after = np.abs(1.0 - np.linalg.norm(lifted, axis=1))
    inner = before > 2e-3                              # off the edges, where the triangle meets the sphere
    print("mean gap to the sphere before/after:", before[inner].mean(), after[inner].mean())
    assert inner.sum() > 1000 and np.all(lift[inner] > 0.0)
    assert np.all(after[inner] < before[inner])


def test_a_view_of_a_split_light_computes_only_the_pixels_it_owns():
    """While one of a light's several views is made (Frame.view_of), common/pixel.glsl's pixel_lit takes
    only the pixels that view owns, so every view's structures and visibility cost its own pixels, not the
    whole frame's (a ball's stand-ins: BACKPROJECTION on `balls` at 96² 12 s → 4 s a frame here, the
    Visibility the same). Checked through the lit-box reduction, which counts with pixel_lit."""
    from penumbra.engine.core.shading import light_defines, light_uniforms
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.frame import Frame
    snap = floating_plane(48)

    def job(worker):
        frame = Frame(worker, snap, RenderSettings())
        try:
            size = (frame.width, frame.height)
            irradiance = frame.texture(size, 4)
            light = snap.lights[0]
            frame.dispatch("shading/irradiance.comp", light_uniforms(light), images={0: irradiance},
                           defines=light_defines(light))
            position = frame.read(frame.gbuffer["g_position"])
            lit = (frame.read(irradiance)[..., 3] > 0) & (position[..., 3] > 0)
            owner = np.where(lit, (position[..., 0] > 0.3).astype(np.float32), -1.0).astype(np.float32)
            owner_tex = frame.texture(size, 1)
            owner_tex.write(owner.tobytes())
            buffer = frame.buffer(bytes(pipeline._BOUNDS_BYTES))
            boxes = []
            centre = (*light.position, 1.0)
            boxes.append(pipeline._lit_bounds(frame, irradiance, buffer, centre)[0])
            for index in (0, 1):
                with frame.view_of(owner_tex, index):
                    boxes.append(pipeline._lit_bounds(frame, irradiance, buffer, centre)[0])
            return boxes, position[..., :3], owner
        finally:
            frame.release()
    boxes, xyz, owner = GpuWorker.get().submit(job).result()
    for box, where in zip(boxes, (owner >= 0, owner == 0, owner == 1)):
        assert where.any()
        assert np.array_equal(box[0], xyz[where].min(axis=0)) and np.array_equal(box[1], xyz[where].max(axis=0))
    assert boxes[2][0][0] > 0.3 >= boxes[1][1][0]
