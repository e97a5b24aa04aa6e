"""SPSM (Lecocq et al. 2014) and its conservative map: the quantiser, conservative coverage, and SPSM against
HARD."""
from __future__ import annotations

import numpy as np
import pytest

from penumbra.engine.core import lightview
from penumbra.engine.core.lightview import LightView
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.core.snapshot import Camera, ObjectInfo, SceneSnapshot
from penumbra.engine.gpu.context import GpuWorker
from penumbra.engine.gpu.frame import NO_OCCLUDER, Frame
from penumbra.engine.structures import conservative_map as cm
from penumbra.engine.measure.stress import look_at, perspective

MAP = 32


# ---- quantiser (§3.4) ------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 3, 5])
def test_quantiser_round_trip_and_clamps(n):
    d = np.concatenate([np.linspace(-50, 50, 2001), [0.0, 1e-6, -1e-6, 1e9, -1e9, np.inf, -np.inf]])
    q = cm.quantise(d, n)
    assert q.min() >= 1 and q.max() <= 253                     # never 0 or 254
    assert cm.quantise(0.0, n) == 127 and cm.dequantise(127, n) == 0.0
    back = cm.dequantise(q, n)
    assert np.all(np.isfinite(back))
    assert np.all(np.sign(back[np.abs(d) > 10]) == np.sign(d[np.abs(d) > 10]))    # no sign flip at ±π/2
    assert np.all(np.diff(cm.quantise(np.sort(d), n).astype(int)) >= 0)           # monotone
    # Round trip: within one code step of the angle (the step of x^n is 1/127 in the power domain).
    inside = (q > 1) & (q < 253)
    theta, theta_back = np.arctan(d[inside]), np.arctan(back[inside])
    x = np.abs(theta) * 2 / np.pi
    step = np.pi / 2 * (np.minimum(x ** n + 1 / 127, 1) ** (1 / n) - np.maximum(x ** n - 1 / 127, 0) ** (1 / n))
    assert np.all(np.abs(theta - theta_back) <= step + 1e-12)
    # The codes hit themselves: decode then encode is the identity on [1, 253].
    codes = np.arange(1, 254)
    assert np.array_equal(cm.quantise(cm.dequantise(codes, n), n), codes)
    table = cm.decode_table(n)
    assert table.dtype == np.float32 and np.all(np.isfinite(table)) and table[0] == table[1]


def test_power_five_is_finer_than_linear_at_grazing_slopes():
    """§3.4: one code step is Δθ = (π/2)·Δy/(n·x^(n−1)) with x = θ/(π/2) and Δy = 1/127. At 80° that is
    0.71° linear and 0.23° for n = 5, a 3.1× gain. (The paper quotes 0.17° and 4× "around 80°"; Eq. 3 gives
    that at ≈ 86°.)"""
    def step_deg(n, angle):
        q = int(cm.quantise(np.tan(np.radians(angle)), n))
        return np.degrees(np.arctan(cm.dequantise(q + 1, n)) - np.arctan(cm.dequantise(q, n)))

    def analytic(n, angle):
        x = angle / 90.0
        return 90.0 / (127.0 * n * x ** (n - 1))
    for n, angle in ((1, 80), (5, 80), (5, 86)):
        assert step_deg(n, angle) == pytest.approx(analytic(n, angle), rel=0.05)
    assert step_deg(1, 80) / step_deg(5, 80) > 3.0
    assert step_deg(5, 86) < 0.18


# ---- conservative rasterization (§3.2) --------------------------------------------------------------------

def _snapshot(triangles: np.ndarray) -> SceneSnapshot:
    t = len(triangles)
    normals = np.zeros_like(triangles)
    normals[..., 2] = 1.0
    cam = Camera("Camera", np.linalg.inv(look_at((0, -3, 3), (0, 0, 0))), perspective(0.8, 1.0, 0.1, 50), 8, 8)
    return SceneSnapshot(triangles.astype(np.float32), normals.astype(np.float32), np.arange(t, dtype=np.int32),
                         np.full((t, 3), 0.5, np.float32), [ObjectInfo(f"T{i}") for i in range(t)], [], cam,
                         name="coverage")


def _render_map(triangles, view, quantiser="POW5"):
    def job(worker, _job):
        frame = Frame(worker, _snapshot(triangles), RenderSettings())
        try:
            m = cm.render(frame, view, quantiser)
            depth = frame.read(m.min_depth)[..., 0].copy()
            texels = np.frombuffer(m.texels.read(), np.uint32).reshape(view.height, view.width, 4).copy()
            return depth, texels
        finally:
            frame.release()
    return GpuWorker.get().run(job)


def _overlaps(tri2d: np.ndarray, size: int, margin: float) -> np.ndarray:
    """CPU separating-axis test of a 2D triangle (texel coordinates) against every texel box grown by
    `margin` texels (negative: shrunk), float64."""
    ys, xs = np.mgrid[0:size, 0:size]
    cx, cy = xs + 0.5, ys + 0.5
    half = 0.5 + margin
    a, b, c = tri2d
    lo, hi = tri2d.min(axis=0), tri2d.max(axis=0)
    ok = (lo[0] <= cx + half) & (hi[0] >= cx - half) & (lo[1] <= cy + half) & (hi[1] >= cy - half)
    for p, q in ((a, b), (b, c), (c, a)):
        axis = np.array([-(q - p)[1], (q - p)[0]])
        if not np.any(axis):
            continue
        proj = tri2d @ axis
        centre = axis[0] * cx + axis[1] * cy
        r = half * (abs(axis[0]) + abs(axis[1]))
        ok &= (proj.min() <= centre + r) & (proj.max() >= centre - r)
    return ok


def _ortho_view(size=MAP):
    window = (-1.0, 1.0, -1.0, 1.0)
    return LightView(np.eye(4), lightview.ortho(window, 1.0, 5.0), size, size, 1.0, 5.0, True, window)


def _random_triangles(rng, count):
    tris = []
    for i in range(count):
        kind = i % 4
        centre = rng.uniform(-0.8, 0.8, 2)
        scale = rng.choice([0.02, 0.1, 0.5])
        xy = centre + rng.normal(0, scale, (3, 2))
        if kind == 1:                       # edge-on: collinear in the map, depth varying along it
            d = rng.normal(0, 1, 2)
            xy = centre + np.outer(rng.uniform(-0.3, 0.3, 3), d / np.linalg.norm(d))
        elif kind == 2:                     # a sliver thinner than a texel
            d = rng.normal(0, 1, 2)
            d /= np.linalg.norm(d)
            xy = centre + np.outer([-0.4, 0.4, 0.1], d) + np.outer([0, 0, 0.004], [-d[1], d[0]])
        z = -rng.uniform(1.5, 4.5, 3)
        tris.append(np.c_[xy, z])
    return np.array(tris)


def test_conservative_rasterization_covers_every_texel_a_triangle_touches():
    """Random triangles (edge-on and sub-texel slivers among them), one map each: every texel the triangle
    overlaps by more than 1e-3 texel is written, and nothing farther than 1e-3 texel from it."""
    rng = np.random.default_rng(12)
    view = _ortho_view()
    for tri in _random_triangles(rng, 24):
        depth, texels = _render_map(tri[None], view)
        covered = depth < NO_OCCLUDER
        tri2d = (tri[:, :2] + 1.0) / 2.0 * MAP
        must = _overlaps(tri2d, MAP, -1e-3)
        may = _overlaps(tri2d, MAP, 1e-3)
        assert np.all(covered[must]), f"{int((must & ~covered).sum())} touched texels missed by {tri.tolist()}"
        assert np.all(may[covered]), f"{int((covered & ~may).sum())} texels written off the triangle"
        assert np.all((texels[covered, 3] & 0xFF) >= 1)        # a written texel has a valid Q code
        # Minimum conservative depth: never behind the triangle's own nearest point in the texel, never
        # nearer than its nearest vertex.
        assert np.all(depth[covered] >= -tri[:, 2].max() - 1e-4)


def test_conservative_map_stores_the_triangle_and_its_plane():
    """A tilted triangle: the stored vertices are the triangle's (texel-relative, 1/64 texel), z̃ is the
    plane's depth at the texel centre (16 bits over [near, far]), the slopes decode to the plane's."""
    view = _ortho_view()
    tri = np.array([[-0.7, -0.6, -1.2], [0.6, -0.5, -4.6], [-0.2, 0.7, -3.0]])
    depth, texels = _render_map(tri[None], view)
    tri2d = (tri[:, :2] + 1.0) / 2.0 * MAP
    j, i = 14, 12                                           # a texel well inside
    centre = np.array([i + 0.5, j + 0.5])
    t = texels[j, i]
    verts = []
    for word in t[:3]:
        x, y = np.int16(word & 0xFFFF), np.int16(word >> 16)
        verts.append(np.array([x, y], float) / cm.VERT_SCALE)
    assert np.allclose(np.array(verts), tri2d - centre, atol=1 / cm.VERT_SCALE)
    # The plane z(x, y) in texel coordinates, from the three vertices.
    A = np.c_[tri2d, np.ones(3)]
    gx, gy, g0 = np.linalg.solve(A, -tri[:, 2])
    z_c = gx * centre[0] + gy * centre[1] + g0
    z_tilde = (t[3] >> 16) / 65535.0 * (5.0 - 1.0) + 1.0
    assert z_tilde == pytest.approx(z_c, abs=1e-4)
    # The GLSL quantiser agrees with its numpy twin (one code of float32 rounding at most) on the plane's
    # slopes per lateral metre; near 0 the n = 5 code is coarse (Q(0.4) is still 127), by design.
    texel_m = 2.0 / MAP                                    # ortho: metres per texel
    for code, slope in (((t[3] >> 8) & 0xFF, gx / texel_m), (t[3] & 0xFF, gy / texel_m)):
        assert abs(int(code) - int(cm.quantise(slope))) <= 1
    # The minimum conservative depth is the plane's nearest corner value.
    assert depth[j, i] == pytest.approx(z_c - 0.5 * (abs(gx) + abs(gy)), abs=1e-4)


def test_near_plane_clipping_keeps_the_visible_part():
    """A perspective view and a triangle that crosses the near plane: the map covers exactly the projection
    of the part in front of it (the clipped polygon, fanned into two triangles)."""
    window = (-1.0, 1.0, -1.0, 1.0)
    near, far = 1.0, 10.0
    view = LightView(np.eye(4), lightview.frustum(window, near, far), MAP, MAP, near, far, False, window)
    tri = np.array([[-0.5, -0.5, -3.0], [0.6, -0.3, -3.0], [0.1, 0.2, -0.2]])   # last vertex before near
    depth, _ = _render_map(tri[None], view)
    covered = depth < NO_OCCLUDER
    # CPU clip against z = -near, then project.
    poly = []
    for k in range(3):
        p, q = tri[k], tri[(k + 1) % 3]
        dp, dq = -p[2] - near, -q[2] - near
        if dp >= 0:
            poly.append(p)
        if (dp >= 0) != (dq >= 0):
            poly.append(p + (q - p) * dp / (dp - dq))
    pts = np.array([(v[:2] / -v[2] + 1.0) / 2.0 * MAP for v in poly])
    must = np.zeros_like(covered)
    may = np.zeros_like(covered)
    for fan in ((0, 1, 2), (0, 2, 3)):
        must |= _overlaps(pts[list(fan)], MAP, -1e-3)
        may |= _overlaps(pts[list(fan)], MAP, 1e-3)
    assert len(poly) == 4 and must.sum() > 20
    assert np.all(covered[must]) and np.all(may[covered])


@pytest.mark.parametrize("tilt", [0.0, 0.6])
def test_stored_depth_stays_exact_with_a_tiny_near_plane(tilt):
    """A caster reaching the light plane sets a perspective view's near plane to 1e-5 of the scene (engine/
    core/lightview.py). η = 1 − window depth is then ~ n/z and float32 keeps ~0.05 % of it: here z̃ came out
    2.9 mm off at 7.4 m; in fuzz 7404 (near 2e-4 m, far 18 m) every triangle's plane came out 1.4 cm nearer,
    beyond its 4 mm bias, and every receiver shadowed itself (SPSM mae_shadow 1.0). The geometry stage now
    takes η from the linear depth (0.14 mm here, under the 16-bit step of 0.3 mm) and the depth test runs on
    linear depth."""
    window = (-0.1, 0.1, -0.1, 0.1)
    near, far = 2e-4, 20.0
    view = LightView(np.eye(4), lightview.frustum(window, near, far), MAP, MAP, near, far, False, window)
    z = 7.4
    tri = np.array([[-0.09 * z, -0.09 * z, -z], [0.09 * z, -0.09 * z, -z - tilt], [0.0, 0.09 * z, -z - tilt]])
    depth, texels = _render_map(tri[None], view)
    j, i = MAP // 2, MAP // 2                               # a texel well inside
    centre = (np.array([i + 0.5, j + 0.5]) / MAP * 2.0 - 1.0) * 0.1     # tangents of the texel centre
    # The plane's depth along the ray through the texel centre: n·(d·(x, y, −1)) = n·p0.
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    z_c = float(n @ tri[0] / (n @ np.array([centre[0], centre[1], -1.0])))
    z_tilde = (texels[j, i, 3] >> 16) / 65535.0 * (far - near) + near
    print("z_c", z_c, "stored", z_tilde, "min depth", depth[j, i])
    assert z_tilde == pytest.approx(z_c, abs=1e-3)
    assert z_c - 0.05 <= depth[j, i] <= z_c + 1e-3           # the plane's nearest corner value


# ---- pattern table (§4.2, derived) -------------------------------------------------------------------------

from penumbra.engine.techniques import spsm  # noqa: E402


def _mask(*names):
    order = ["E", "NE", "N", "NW", "W", "SW", "S", "SE"]
    return sum(1 << order.index(n) for n in names)


def test_pattern_set():
    d = spsm.pattern_directions
    # An edge beside the centre: the tangent faces the occluders.
    assert np.allclose(d(_mask("E"), False), [[1, 0]])
    assert np.allclose(d(_mask("NE", "E", "SE"), False), [[1, 0]])
    assert np.allclose(d(_mask("E", "NE", "N"), False), [[np.sqrt(0.5), np.sqrt(0.5)]])
    # Isolated corners say nothing (Fig. 7c); a corner joined to an edge counts.
    assert d(_mask("NE"), False) == [] and d(_mask("NE", "SW"), False) == []
    assert np.allclose(d(_mask("NE", "SW", "W"), False), [np.array([-2, -1]) / np.sqrt(5)])
    # Two occluders on either side of an empty centre: two tangents, each facing its own.
    two = d(_mask("E", "W"), False)
    assert len(two) == 2 and np.allclose(sorted(x[0] for x in two), [-1, 1])
    # The centre in front with a lopsided blob: an edge; a line through the centre: a thin occluder with
    # both normals of its axis.
    assert np.allclose(d(_mask("N", "NE", "NW", "E", "W"), True), [[0, 1]])
    thin = d(_mask("E", "W"), True)
    assert len(thin) == 2 and np.allclose(np.abs(thin), [[0, 1], [0, 1]])
    diag = d(_mask("NE", "SW", "N", "S"), True)      # a line from SW to NE (through N and S texels too)
    assert len(diag) == 2 and np.allclose(diag[0], -diag[1])
    assert d(0, True) == [] and d(_mask("NE"), True) == []
    table = spsm.pattern_table()
    assert table.shape == (512, 4)
    lengths = np.linalg.norm(table.reshape(512, 2, 2), axis=2)
    assert np.all(np.isclose(lengths, 1.0) | (lengths == 0.0))


def test_every_pattern_faces_its_occluders():
    """For every mask with the centre clear, each direction points into the set texels of some group."""
    for mask in range(256):
        groups = spsm.ring_groups(mask)
        for direction in spsm.pattern_directions(mask, False):
            assert any(np.dot(np.sum([spsm.RING[i] for i in g], axis=0), direction) > 0 for g in groups)


# ---- SPSM against HARD -------------------------------------------------------------------------------------

from penumbra.engine.measure import metrics, stress  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402


def _hard_scene(img):
    """A rotated square, a box and ribbons of 1–4 cm over a ground, a 1 mm light (hard shadows)."""
    c = np.array([0.2, 0.1, 1.0])
    a = 0.37
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    occ = (stress.quad(tuple(c), 0.5) - c) @ rot.T + c
    bars = np.concatenate([stress.strip((-2.5, -1.0 + 0.3 * i), (-0.8, -0.6 + 0.3 * i), 0.01 + 0.01 * i, 0.8)
                           for i in range(4)])
    parts = [("Ground", stress.quad((0, 0, 0), 4.0), True, True), ("Occluder", occ, True, True),
             ("Bars", bars, True, True), ("Box", stress.box((1.0, -1.6, 0.0), (1.6, -0.9, 0.7)), True, True)]
    return stress.assemble(parts, [stress.area_light((0.3, 0.2, 3.0), size=1e-3)], stress.camera(size=img),
                           "spsm_test")


@pytest.mark.parametrize("map_size", [64, 128, 256])
def test_spsm_matches_the_hard_truth_better_than_hard(map_size):
    """Against a ray-traced hard shadow (one ray to the light's centre per pixel), SPSM puts no more pixels
    on the wrong side of 0.5 than HARD at the same map size, and never gives NaN."""
    snap = _hard_scene(96)
    ref = stress.oracle(snap, n=1)["V"]
    mask = np.isfinite(ref)
    wrong = {}
    for tech in ("HARD", "SPSM"):
        v = pipeline.render(snap, RenderSettings(technique=tech, shadow_map_size=map_size)).passes["Visibility"]
        assert np.isfinite(v).all()
        m = metrics.compare(v[..., 0], np.nan_to_num(ref), mask)
        wrong[tech] = (1.0 - m["pixel_match"]) * m["n_mask"]
    print(map_size, wrong)
    assert wrong["SPSM"] <= wrong["HARD"]


def test_a_small_window_over_deep_casters_keeps_the_receivers_own_triangles_lit():
    """The texel keeps its plane's depth in 16 bits over the view's depth range: with a window of centimetres
    over casters tens of metres deep (a camera close to a huge faceted object; fuzz 27002, a 15× Suzanne) one
    step is many texels wide, wider than the bias, and the receivers' own triangles came out in front of them
    in stripes (39 % of this ball's lit top dark before such receivers were decided by the float depth map, as
    HARD decides them). A ray-traced hard shadow lights every pixel."""
    ball = stress.sphere((0.0, 0.0, -20.0), 20.0, rings=24)
    snap = stress.assemble([("Ball", ball, True, True)], [stress.area_light((3.0, 1.0, 30.0), size=1e-3)],
                           stress.camera(eye=(0.3, -0.6, 0.6), target=(0.0, 0.0, 0.0), fov=2.0, size=48),
                           "big_ball")
    assert np.nanmin(stress.oracle(snap, n=1)["V"]) == 1.0
    v = pipeline.render(snap, RenderSettings(technique="SPSM")).passes["Visibility"][..., 0]
    assert (v < 0.5).mean() == 0.0


def test_spsm_classes_and_options_are_finite():
    snap = _hard_scene(48)
    for extra in ({"spsm_quantiser": q} for q in cm.QUANTISERS):
        r = pipeline.render(snap, RenderSettings(technique="SPSM", shadow_map_size=64, collect_stats=True,
                                                 debug_passes=True).with_(**extra))
        v = r.passes["Visibility"]
        assert np.isfinite(v).all() and v.min() >= 0 and v.max() <= 1
        stats = r.stats["per_light"][0]
        assert sum(stats[f"share_{n}"] for n in spsm.CLASSES.values()) == pytest.approx(1.0)
        assert stats["share_recovered"] > 0 and stats["share_shadow_1"] > 0
    r = pipeline.render(snap, RenderSettings(technique="SPSM", shadow_map_size=64).with_(spsm_recovery=False,
                                                                                          spsm_aa_samples=1))
    assert np.isfinite(r.passes["Visibility"]).all()


@pytest.mark.parametrize("name", ["suzanne", "contact", "thin"])
def test_spsm_at_least_as_good_as_hard_against_cycles(name):
    """Built-in scenes with a 1 cm light against Cycles (128², 512² maps): SPSM's pixel_match ≥ HARD's."""
    bpy = pytest.importorskip("bpy")
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.measure import reference
    from penumbra.engine.measure.studies import spsm as study
    sc = study._scene(name, 128)
    ref = reference.cycles_visibility(sc, samples=64)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    match = {}
    for tech in ("HARD", "SPSM"):
        v = pipeline.render(snap, RenderSettings(technique=tech, shadow_map_size=512)).passes["Visibility"]
        assert np.isfinite(v).all()
        match[tech] = metrics.compare(v[..., 0], ref.visibility, ref.mask)["pixel_match"]
    print(name, match)
    assert match["SPSM"] >= match["HARD"]


def test_study_edge_pixels_and_score():
    from penumbra.engine.measure.studies import spsm as study
    ref = np.ones((6, 6))
    ref[:, :3] = 0.0
    edges = study.edge_pixels(ref, np.ones_like(ref, bool))
    assert edges[:, 2:4].all() and not edges[:, :2].any() and not edges[:, 4:].any()
    v = ref.copy()
    v[0, 3] = 0.0                                           # one false shadow on the edge
    s = study.score(v, ref, np.ones_like(ref, bool))
    assert s["mismatched"] == 1 and s["false_shadow"] == 1 and s["boundary_rate"] == pytest.approx(1 / 12)
    assert s["recall"] == 1.0


def wide_sun_ball(resolution, angle):
    """A smooth ball (0.8 m) resting on the floor under a sun `angle` radians wide at 50° elevation, seen
    from the side away from the sun: the ball's far half faces away from the sun's centre yet is lit by the
    rest of its disk, and its shadow is a wide penumbra (fuzz seeds 6032 and 5016's class). Reuses the
    built-in scenes' helpers; returns the bpy scene."""
    import math

    import bpy
    from penumbra.engine.measure import scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    scenes._setup_scene(sc, resolution)
    scenes._add_ground(sc)
    occ = scenes.diffuse_material("OccluderMaterial", scenes.OCCLUDER_RGB)
    ball = scenes._link(sc, bpy.data.objects.new("Ball", scenes._uv_sphere_mesh("Ball", 0.8, occ)))
    ball.location = (0.0, 0.0, 0.8)
    elevation = math.radians(50.0)
    scenes._add_sun(sc, (math.cos(elevation), 0.0, math.sin(elevation)), angle)
    scenes._add_camera(sc, (-4.0, -2.5, 2.5), (0.3, 0.0, 0.5), lens=35)
    bpy.context.view_layer.update()
    return sc


def wide_sun_ball_errors(angle, techniques, resolution=(64, 64)) -> dict:
    """mae_shadow of each technique on wide_sun_ball against Cycles (256 spp)."""
    import bpy
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.measure import metrics, reference
    from penumbra.engine.render import pipeline
    sc = wide_sun_ball(resolution, angle)
    ref = reference.cycles_visibility(sc, samples=256)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    out = {}
    for tech in techniques:
        v = pipeline.render(snap, RenderSettings(technique=tech)).passes["Visibility"][..., 0]
        out[tech] = metrics.compare(v, ref.visibility, ref.mask)["mae_shadow"]
    print(angle, out)
    return out


def lowpoly_ball_terminator(resolution):
    """A smooth low-poly ball (10 × 6 segments, 0.8 m) on the floor, a 0.5 m square light 18° above its
    equator, seen side-on: its shadow terminator runs across the camera's view (fuzz seed 9's class)."""
    import math

    import bpy
    from penumbra.engine.measure import scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    scenes._setup_scene(sc, resolution)
    scenes._add_ground(sc)
    occ = scenes.diffuse_material("OccluderMaterial", scenes.OCCLUDER_RGB)
    ball = scenes._link(sc, bpy.data.objects.new("Ball", scenes._uv_sphere_mesh("Ball", 0.8, occ, u=10, v=6)))
    ball.location = (0.0, 0.0, 0.8)
    e = math.radians(18.0)
    scenes._add_area_light(sc, (4.0 * math.cos(e), 0.0, 0.8 + 4.0 * math.sin(e)), (0.0, 0.0, 0.8), 0.5)
    scenes._add_camera(sc, (0.0, -3.5, 1.6), (0.0, 0.0, 0.7), lens=35)
    bpy.context.view_layer.update()
    return sc


def _spsm_and_hard_against_cycles(sc):
    """mae_shadow of HARD and SPSM against Cycles (256 spp) and the share of the pixels Cycles sees lit
    (V ≥ 0.95) that SPSM puts below 0.5."""
    bpy = pytest.importorskip("bpy")
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.measure import reference
    ref = reference.cycles_visibility(sc, samples=256)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    lit = ref.mask & (ref.visibility >= 0.95)
    assert lit.sum() > 1000
    mae = {}
    for tech in ("HARD", "SPSM"):
        v = pipeline.render(snap, RenderSettings(technique=tech)).passes["Visibility"][..., 0]
        mae[tech] = metrics.compare(v, ref.visibility, ref.mask)["mae_shadow"]
    dark = float(np.mean(v[lit] < 0.5))
    print(mae, "SPSM: share of Cycles-lit pixels below 0.5:", dark)
    return mae, dark


def test_spsm_lights_receivers_facing_away_from_a_wide_suns_centre():
    """A 2.5 rad sun on a ball (64²): the ball's far half faces away from the sun's centre and Cycles has it
    lit. SPSM decided those pixels against the hard map without HARD's tangent-plane rule, so the ball
    shadowed itself: 6.6 % of the pixels Cycles sees lit came out below 0.5 and mae_shadow was 0.207 against
    HARD's 0.138 (fuzz 6032: 0.45 against a bound of 0.25). SPSM now decides every pixel whose triangle faces
    away from the light centre as HARD does."""
    pytest.importorskip("bpy")
    mae, dark = _spsm_and_hard_against_cycles(wide_sun_ball((64, 64), 2.5))
    assert dark <= 0.005
    assert mae["SPSM"] <= mae["HARD"] + 0.005


def test_spsm_terminator_starts_where_cycles_shadow_ray_does():
    """The low-poly ball's terminator (64²): SPSM compared the unlifted surface point with the hard map there,
    a dark streak along the terminator that Cycles' lifted shadow rays do not see (0.6 % of the lit pixels
    below 0.5, mae_shadow 0.074 against HARD's 0.047; fuzz seed 9: 0.263 against a bound of 0.261). It now
    takes HARD's lifted receiver (common/light_view.glsl pixel_receiver) there, position and depth alike."""
    pytest.importorskip("bpy")
    mae, dark = _spsm_and_hard_against_cycles(lowpoly_ball_terminator((64, 64)))
    assert dark <= 0.001
    assert mae["SPSM"] <= mae["HARD"] + 0.005
