"""SSM (Atty et al. 2006): closed form, roles, precision (appendix A), two-pass (§3.5), stability, culling."""
import numpy as np
import pytest

from penumbra.engine.render import pipeline
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.core.snapshot import ObjectInfo, SceneSnapshot
from penumbra.engine.techniques import ssm
from penumbra.tests.synthetic import floating_plane, quad
from penumbra.tests.test_pipeline import _ground_depth, exact_area_visibility, ground_points


def _ssm(**options):
    return RenderSettings(technique="SSM").with_(**options)


def _ground_error(snap, r, light_half=0.5, occ_half=0.5, occ_height=1.0, light_height=3.0):
    pts = ground_points(snap)
    on_ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, pts)) < 1e-3
    exact = exact_area_visibility(pts, light_half, occ_half, occ_height, light_height)
    return np.abs(r.passes["Visibility"][..., 0] - exact)[on_ground & (exact < 0.99)]


def test_parallel_planes_match_the_closed_form():
    """Parallel square occluder and light: the micro-patches tile the occluder exactly (no overlap or gap,
    §4.1.2), so only discretisation remains (§4.1.1): the occluder's map-aligned edges move by ≤ ½ texel.
    At 128² the map spans ≈ 0.70 (tangent) → ½ texel ≈ 0.0027 tangent ≈ 8 mm on the ground (depth 3),
    against a 1 m wide penumbra ramp: |ΔV| ≤ 0.008 near an edge, less on average; plus the SSM's bilinear
    reconstruction. Tolerance: mean 0.008, p99 0.02 (measured: 0.0036, 0.008)."""
    snap = floating_plane(96)
    # The closed form is the plain share of the light (the paper's model): uniform weighting.
    r = pipeline.render(snap, _ssm(ssm_map_size=128, ssm_weighting="UNIFORM"))
    err = _ground_error(snap, r)
    print("SSM vs closed form: mean", err.mean(), "p99", np.percentile(err, 99))
    assert err.size > 500
    assert err.mean() < 0.008
    assert np.percentile(err, 99) < 0.02


def test_irradiance_weighting_matches_the_weighted_reference():
    """ssm_weighting=IRRADIANCE weights each micro-patch's hidden rectangle of the light by its share of
    the irradiance at a receiver facing the light (parallel-rectangle form factor). On the parallel planes the
    receivers do face the light, so this is the irradiance-weighted visibility REFERENCE computes: the same
    bounds as the unweighted closed form, and clearly closer than uniform weighting."""
    snap = floating_plane(96)
    ref = pipeline.render(snap, RenderSettings(technique="REFERENCE", shadow_map_size=1024)
                          .with_(averaged_light_samples=256)).passes["Visibility"][..., 0]
    pts = ground_points(snap)
    errors = {}
    for weighting in ("IRRADIANCE", "UNIFORM"):
        r = pipeline.render(snap, _ssm(ssm_map_size=128, ssm_weighting=weighting))
        on_ground = np.abs(r.passes["Depth"][..., 0] - _ground_depth(snap, pts)) < 1e-3
        v = r.passes["Visibility"][..., 0]
        sel = on_ground & ((v < 0.99) | (ref < 0.99))
        errors[weighting] = np.abs(v - ref)[sel].mean()
    print(errors)
    assert errors["IRRADIANCE"] < 0.008
    assert errors["IRRADIANCE"] < 0.5 * errors["UNIFORM"]


@pytest.mark.parametrize("precision", ["FLOAT32", "HALF", "HALF_BATCHED"])
@pytest.mark.parametrize("passes", ["ONE", "TWO"])
@pytest.mark.parametrize("scatter", ["RASTER", "COMPUTE"])
def test_every_option_is_finite_and_bounded(precision, passes, scatter):
    if scatter == "COMPUTE" and precision != "FLOAT32":
        pytest.skip("the compute scatter accumulates in fixed point; precision applies to blending")
    snap = floating_plane(40)
    r = pipeline.render(snap, _ssm(ssm_map_size=64, ssm_precision=precision, ssm_passes=passes,
                                   ssm_scatter=scatter, ssm_budget=50.0), )
    for name, array in r.passes.items():
        assert np.isfinite(array).all(), name
    v = r.passes["Visibility"][..., 0]
    assert 0.0 <= v.min() and v.max() <= 1.0
    # The umbra: exact with float32 / fixed point; FP16 without batching stalls short of it (appendix A).
    assert v.min() < (0.15 if precision == "HALF" else 0.03)
    assert (v == 1.0).mean() > 0.5


def test_compute_scatter_equals_raster_scatter():
    snap = floating_plane(48)
    a = pipeline.render(snap, _ssm(ssm_map_size=64, ssm_scatter="RASTER")).passes["Visibility"]
    b = pipeline.render(snap, _ssm(ssm_map_size=64, ssm_scatter="COMPUTE")).passes["Visibility"]
    assert np.abs(a - b).max() < 1e-4


@pytest.mark.heavy
def test_compute_scatter_of_patches_wider_than_the_loop_limit_equals_raster_scatter():
    """A light 10× the occluder, 1 m below it over a floor 2 m further: every patch's rectangle covers the
    whole 384² map (147k texels), more than llvmpipe runs loop iterations in one invocation (65535).
    (ssm_budget raised so that the map stays 384².) Unsplit, each patch stopped after its first 65535
    texels: the far rows of the map missed all their shadow (at 512²: |compute − raster| up to 0.093, all
    of it). Split over dispatches the compute scatter adds every texel."""
    from dataclasses import replace
    from penumbra.engine.measure import stress
    snap = replace(stress.plane_scene(occluder_height=2.0, light_size=10.0), camera=stress.camera(size=24))
    a = pipeline.render(snap, _ssm(ssm_map_size=384, ssm_budget=1e4, ssm_scatter="RASTER")).passes["Visibility"]
    r = pipeline.render(snap, _ssm(ssm_map_size=384, ssm_budget=1e4, ssm_scatter="COMPUTE", collect_stats=True))
    assert r.stats["ssm_scatter_dispatches"] > 4
    assert a.min() < 0.95 and np.abs(a - r.passes["Visibility"]).max() < 1e-3     # shadow 0.09 deep


@pytest.mark.heavy
def test_half_float_fails_at_large_maps_and_float32_or_batching_fix_it():
    """Appendix A on the synthetic parallel planes: at 256² a micro-patch hides ~1e-4 of the light, below
    2^-11 of a running FP16 sum past ~0.2, so FP16 blending stalls (the umbra never gets dark)."""
    snap = floating_plane(48)
    errs = {p: _ground_error(snap, pipeline.render(snap, _ssm(ssm_map_size=256, ssm_precision=p))).mean()
            for p in ("FLOAT32", "HALF", "HALF_BATCHED")}
    print(errs)
    assert errs["HALF"] > 0.1
    assert errs["FLOAT32"] < 0.1 * errs["HALF"]
    assert errs["HALF_BATCHED"] < 0.2 * errs["HALF"]


def test_occluder_touching_the_light_stays_finite():
    """zo → 0: the spread 1/zo − 1/zr grows without bound; extents are clamped to the map and nothing
    divides by zero. The occluder as large as the light, 1 mm below it, hides nearly all of it."""
    snap = floating_plane(40, occluder_height=2.999, light_height=3.0)
    r = pipeline.render(snap, _ssm(ssm_map_size=64))
    v = r.passes["Visibility"][..., 0]
    assert np.isfinite(v).all() and 0.0 <= v.min() and v.max() <= 1.0
    err = _ground_error(snap, r, occ_height=2.999)
    # Accuracy is another matter (§4.2.6: the error grows as the occluder nears the light): seen from the
    # light centre this occluder spans a hemisphere, and the map, clamped to ±80°, holds only its middle.
    print("touching the light: mean error", err.mean())
    assert np.isfinite(err).all()


def _stacked(roles):
    """Ground, a plate at 1.0 (x 0.3 … 0.9) partly in the penumbra of a plate at 2.0 (x, y ±0.3), light at
    3.0, with the given roles. Seen from the light centre the lower plate sticks out beyond x = 0.6."""
    snap = floating_plane(96)
    lower, upper = quad((0.6, 0.0, 1.0), 0.3), quad((0.0, 0.0, 2.0), 0.3)
    positions = np.concatenate([snap.positions[:2], lower, upper])
    normals = np.zeros_like(positions)
    normals[..., 2] = 1.0
    object_id = np.r_[snap.object_id, [2, 2]].astype(np.int32)
    albedo = np.full((len(positions), 3), 0.8, np.float32)
    objects = [ObjectInfo(n, role=r) for n, r in zip(("Ground", "Lower", "Upper"), roles)]
    return SceneSnapshot(positions, normals, object_id, albedo, objects, snap.lights, snap.camera, name="stacked")


def test_receiver_only_object_casts_nothing():
    snap = floating_plane(40)
    snap.objects[1].role = "RECEIVER"
    r = pipeline.render(snap, _ssm())
    assert np.all(r.passes["Visibility"] == 1.0)


def test_caster_only_object_receives_nothing():
    """The lower plate lies in the upper plate's shadow: as BOTH it is shadowed, as CASTER it is not; the
    ground is shadowed either way."""
    both = pipeline.render(_stacked(("BOTH", "BOTH", "BOTH")), _ssm())
    caster = pipeline.render(_stacked(("BOTH", "CASTER", "BOTH")), _ssm())
    depth = both.passes["Depth"][..., 0]
    snap = _stacked(("BOTH",) * 3)
    lower = np.abs(depth - _plate_depth(snap, 1.0)) < 1e-3
    assert lower.sum() > 50
    assert both.passes["Visibility"][..., 0][lower].min() < 0.8
    assert np.all(caster.passes["Visibility"][..., 0][lower] == 1.0)
    ground = np.abs(depth - _plate_depth(snap, 0.0)) < 1e-3
    assert caster.passes["Visibility"][..., 0][ground].min() < 0.1


def _plate_depth(snap, z):
    cam = snap.camera
    w, h = cam.width, cam.height
    xs, ys = (np.arange(w) + 0.5) / w * 2 - 1, (np.arange(h) + 0.5) / h * 2 - 1
    ndc = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    inv = np.linalg.inv(cam.projection @ cam.view)
    near = np.c_[ndc, -np.ones(len(ndc)), np.ones(len(ndc))] @ inv.T
    far = np.c_[ndc, np.ones(len(ndc)), np.ones(len(ndc))] @ inv.T
    near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
    t = (near[:, 2] - z) / (near[:, 2] - far[:, 2])
    p = near + (far - near) * t[:, None]
    hom = np.c_[p, np.ones(len(p))] @ cam.view.T
    return -hom[:, 2].reshape(h, w)


@pytest.mark.parametrize("role, missing", [("RECEIVER", "Caster"), ("CASTER", "Receiver")])
def test_warns_when_a_role_is_missing(role, missing):
    snap = floating_plane(32)
    for o in snap.objects:
        o.role = role
    r = pipeline.render(snap, _ssm())
    assert any(f"no object with Shadow Role {missing}" in w for w in r.warnings), r.warnings
    assert np.all(r.passes["Visibility"] == 1.0)
    assert "ssm_scatter" not in r.timings


def test_casters_far_from_the_visible_receivers_cost_nothing():
    """The occluder sits 20 m to the side: its penumbra cannot reach what the camera sees, so no map is
    rendered and nothing is scattered."""
    snap = floating_plane(32)
    snap.positions[2:, :, 0] += 20.0
    r = pipeline.render(snap, _ssm())
    assert "ssm_maps" not in r.timings and "ssm_scatter" not in r.timings
    assert r.stats.get("ssm_lights_skipped") == 1
    assert np.all(r.passes["Visibility"] == 1.0)


@pytest.mark.parametrize("light_aspect", [True, False])
def test_view_has_the_lights_aspect_ratio(light_aspect):
    """§3.2 (ssm_texels LIGHT): occluder-map texels have the light's aspect ratio; by default they are square.
    Either way the longer side gets the map size and the window holds the pipeline's."""
    from penumbra.engine.core.lightview import LightView
    base = LightView(np.eye(4), np.eye(4), 10, 10, 0.1, 10.0, False, (-1.0, 1.0, -0.8, 0.8))
    v = ssm.ssm_view(base, (1.0, 0.5), 128, light_aspect)     # light twice as wide as tall
    tw, th = v.texel_size()
    assert abs(tw / th - (2.0 if light_aspect else 1.0)) < 1e-9
    assert max(v.width, v.height) == 128
    x0, x1, y0, y1 = v.window
    assert x0 <= -1.0 and x1 >= 1.0 and y0 <= -0.8 and y1 >= 0.8


bpy = None
try:
    import bpy  # noqa: F401
except Exception:   # pragma: no cover
    pass


@pytest.mark.skipif(bpy is None, reason="needs bpy")
def test_two_pass_is_not_worse_than_one_pass_on_suzanne():
    """§3.5 against Cycles (256 spp, cached; the reference shared with test_against_cycles)."""
    from penumbra.engine.measure import metrics, reference, scenes
    from penumbra.engine.blender.extract import extract
    sc = scenes.build("suzanne", resolution=(128, 128))
    ref = reference.cycles_visibility(sc, samples=256)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    err = {}
    for passes in ("ONE", "TWO"):
        r = pipeline.render(snap, _ssm(ssm_passes=passes))
        err[passes] = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)["mae_shadow"]
    print("suzanne mae_shadow", err)
    assert err["TWO"] <= err["ONE"]


@pytest.mark.skipif(bpy is None, reason="needs bpy")
def test_float32_beats_half_float_at_512_on_plane():
    """Appendix A on the `plane` scene at ssm_map_size 512 (the work budget lowers the map where the
    scatter would exceed it; both precisions get the same map): FP16 blending loses the small micro-patch
    contributions, float32 does not."""
    from penumbra.engine.measure import metrics, reference, scenes
    from penumbra.engine.blender.extract import extract
    sc = scenes.build("plane", resolution=(64, 64))
    ref = reference.cycles_visibility(sc, samples=64)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    err = {}
    for precision in ("FLOAT32", "HALF"):
        r = pipeline.render(snap, _ssm(ssm_map_size=512, ssm_precision=precision))
        err[precision] = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)["mae_shadow"]
        print(precision, r.stats.get("ssm_map_size"), err[precision], r.warnings)
    assert err["FLOAT32"] < 0.5 * err["HALF"]


def _gpu_and_reference_rows(monkeypatch, snap, settings):
    """Render `snap` and return (result, [(GPU rows, GPU work, patch_list rows, patch_list work)] for every
    occluder map of every light view), the reference computed from the same maps."""
    from penumbra.engine import structures
    from penumbra.engine.structures import ssm_maps
    seen = []
    inner = structures.BUILDERS[ssm_maps.SSM_MAPS]

    def build(frame, lc, **params):
        maps = inner.build(frame, lc, **params)
        if maps.view is not None:
            for gpu, (rows, work) in zip(maps.patches, ssm_maps.reference_patches(frame, maps)):
                seen.append((gpu.read(), gpu.work, rows, work))
        return maps
    monkeypatch.setitem(structures.BUILDERS, ssm_maps.SSM_MAPS, structures.Builder(build, inner.requires))
    return pipeline.render(snap, settings), seen


def _with_light(snap, **changes):
    from dataclasses import replace
    return replace(snap, lights=[replace(snap.lights[0], **changes)])


def _thick_plate():
    """floating_plane's occluder with an underside 0.2 below it, facing down: the back-face occluder map of
    two passes (§3.5) holds it."""
    snap = floating_plane(32)
    positions = np.concatenate([snap.positions, quad((0.0, 0.0, 0.8), 0.5, normal_up=False)])
    normals = np.zeros_like(positions)
    normals[..., 2] = 1.0
    normals[-2:, :, 2] = -1.0
    object_id = np.r_[snap.object_id, [1, 1]].astype(np.int32)
    albedo = np.full((len(positions), 3), 0.8, np.float32)
    return SceneSnapshot(positions, normals, object_id, albedo, snap.objects, snap.lights, snap.camera,
                         name="thick_plate")


@pytest.mark.parametrize("case", ["area_two_pass", "stacked_one_pass", "sun_two_pass", "touching_light",
                                  "point_light", "lowered_by_budget"])
def test_gpu_patch_list_equals_the_numpy_reference(monkeypatch, case):
    """glsl/ssm/patches.comp builds the rows patch_list gives, in the same (texel) order, and the same work
    estimate; the stats count them. Cases: two passes, three objects at three depths, an ortho view (sun),
    extents clamped at the map (an occluder 1 mm below the light), the cube faces of a point light, and a
    map the work budget made coarser."""
    from penumbra.engine.core.snapshot import POINT, SUN
    snap, options = _thick_plate(), dict(ssm_map_size=64, ssm_passes="TWO")
    if case == "stacked_one_pass":
        snap, options["ssm_passes"] = _stacked(("BOTH",) * 3), "ONE"
    elif case == "sun_two_pass":
        snap = _with_light(snap, kind=SUN, angle=np.radians(10.0), power=3.0)
    elif case == "touching_light":
        snap, options["ssm_passes"] = floating_plane(32, occluder_height=2.999, light_height=3.0), "ONE"
    elif case == "point_light":
        snap = _with_light(snap, kind=POINT, radius=0.4)
    elif case == "lowered_by_budget":
        options.update(ssm_map_size=256, ssm_budget=1.0)
    r, seen = _gpu_and_reference_rows(monkeypatch, snap, _ssm(**options))
    assert seen and sum(len(ref) for _, _, ref, _ in seen) > 0
    if options["ssm_passes"] == "TWO":
        assert len(seen[1][2]) > 0          # the back-face map has patches too
    for gpu, gpu_work, ref, ref_work in seen:
        assert gpu.shape == ref.shape
        np.testing.assert_allclose(gpu, ref, rtol=1e-6, atol=0.0)    # double on both sides: a few float ulps
        assert gpu_work == pytest.approx(ref_work, rel=1e-12)
    assert r.stats["ssm_patches"] == sum(len(ref) for _, _, ref, _ in seen)
    assert abs(r.stats["ssm_work"] - int(sum(w for *_, w in seen))) <= 1
    if case == "lowered_by_budget":
        assert r.stats["ssm_map_size"] < 256 and any("lowered" in w for w in r.warnings)


def _ball_on_ground(size=40):
    """A 1.2 m ball resting on the ground under a 1.6 m area light 2.6 m up and 0.4 m to the side: the light
    sees the ball's flank obliquely, so from a receiver in the penumbra that surface folds over itself."""
    from penumbra.engine.measure import stress
    parts = [("Ground", stress.quad((0, 0, 0), 4.0), True, True),
             ("Ball", stress.sphere((0.0, 0.0, 0.6), 0.6, rings=10), True, True)]
    return stress.assemble(parts, [stress.area_light((0.4, 0.0, 2.6), size=1.6)],
                           stress.camera(eye=(0.0, -3.5, 4.5), size=size), "ball")


@pytest.mark.heavy
def test_sloped_facets_neither_gap_nor_overlap_over_a_curved_caster():
    """Against ray-traced visibility (stress.oracle, 100 light points). The paper's flat micro-patches sum to
    more than the ball hides, where its flank folds over itself as a receiver sees it: measured mae 0.053.
    Sloped facets (ssm_facets, the default) meet their neighbours on the light and subtract where seen from
    behind: 0.0095. Bounds: facets under 0.02, and flat patches at least 3× worse (the test fails if either
    mechanism changes). The compute scatter's signed fixed-point sums equal the raster scatter's."""
    from penumbra.engine.measure import stress
    snap = _ball_on_ground()
    oracle = stress.oracle(snap, n=10)["V"]
    errors = {}
    for facets in (True, False):
        v = pipeline.render(snap, _ssm(ssm_facets=facets)).passes["Visibility"][..., 0]
        known = np.isfinite(oracle)
        shadow = known & ((v < 0.99) | (oracle < 0.99))
        assert shadow.sum() > 200
        errors[facets] = float(np.abs(v - oracle)[shadow].mean())
        if facets:
            c = pipeline.render(snap, _ssm(ssm_facets=True, ssm_scatter="COMPUTE")).passes["Visibility"][..., 0]
            assert np.abs(c - v).max() < 1e-4
    print(errors)
    assert errors[True] < 0.02
    assert errors[False] > 3.0 * errors[True]


@pytest.mark.heavy
def test_sloped_facets_of_a_sheet_the_receivers_see_from_the_lights_side():
    """A 1.2 m sheet tilted 70° under an 8 m area light 1 m above it: the light reaches past the sheet's plane,
    so receivers beside it see its lit side and its facets' back-projection turns over (a negative sum whose
    size is the light the sheet hides). Against ray-traced visibility, measured: facets 0.0092, facets
    clamped at 0 instead of taking the sum's size 0.0216, flat micro-patches 0.0209."""
    from penumbra.engine.measure import stress
    c, s = np.cos(np.radians(70.0)), np.sin(np.radians(70.0))
    sheet = stress.quad((0, 0, 0), 0.6) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T + np.array([0, 0, 1.0])
    snap = stress.assemble([("Ground", stress.quad((0, 0, 0), 4.0), True, True), ("Sheet", sheet, True, True)],
                           [stress.area_light((0.0, 0.0, 2.0), size=8.0)],
                           stress.camera(eye=(0.0, -3.5, 4.5), size=40), "sheet")
    oracle = stress.oracle(snap, n=10)["V"]
    errors = {}
    for facets in (True, False):
        v = pipeline.render(snap, _ssm(ssm_facets=facets)).passes["Visibility"][..., 0]
        shadow = np.isfinite(oracle) & ((v < 0.99) | (oracle < 0.99))
        assert shadow.sum() > 800
        errors[facets] = float(np.abs(v - oracle)[shadow].mean())
    print(errors)
    assert errors[True] < 0.015
    assert errors[True] < 0.6 * errors[False]


def test_refined_size_follows_the_penumbra_width_up_to_the_fine_size():
    from penumbra.engine.structures.ssm_maps import PENUMBRA_TEXELS, refined_size
    assert refined_size(256, 1024, work=100.0, patches=100) == 1024          # one texel a patch: hard
    assert refined_size(256, 1024, work=400.0 * 4, patches=400) == int(256 * PENUMBRA_TEXELS / 2.0)
    assert refined_size(256, 1024, work=25.0 * 100, patches=100) == 256       # 5 texels wide: soft enough
    assert refined_size(256, 0, work=100.0, patches=100) == 256               # off
    assert refined_size(256, 1024, work=0.0, patches=0) == 256                # nothing to scatter
