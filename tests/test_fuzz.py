"""The differential test against Cycles on random scenes (engine/measure/fuzz.py, issue 10).

Cheap: the generator is deterministic per seed and covers every primitive, transform, light type and shape over
a seed range (no rendering). Default run: a few fixed seeds, every technique against Cycles at 64², and the
issue's flattened-caster and wide-sun cases. `-m slow`: a 200-scene sweep per technique.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import fuzz  # noqa: E402
from penumbra.engine.render.pipeline import TECHNIQUES  # noqa: E402

COVERAGE_SEEDS = range(200)


def test_generator_is_deterministic_per_seed():
    for seed in (0, 7, 123):
        assert fuzz.scene_params(seed) == fuzz.scene_params(seed)
        assert fuzz.describe(fuzz.scene_params(seed)) == fuzz.describe(fuzz.scene_params(seed))
    assert fuzz.scene_params(1) != fuzz.scene_params(2)


def test_build_is_deterministic():
    def state(seed):
        scene = fuzz.build(fuzz.scene_params(seed), (32, 32))
        obs = {ob.name: (ob.type, tuple(round(v, 9) for row in ob.matrix_world for v in row),
                         len(ob.data.polygons) if ob.type == "MESH" else None) for ob in scene.objects}
        return obs, scene.camera.data.type
    for seed in (3, 41):
        assert state(seed) == state(seed)


@pytest.mark.parametrize("primitive", fuzz.PRIMITIVES)
def test_primitive_corners_do_not_depend_on_the_run(primitive):
    """The face corners in a fixed order (scenes.mesh_from_bmesh), not bmesh's, which follows memory
    addresses: the Cycles cache key and every float sum over the triangles stay the same across runs."""
    def corners(name):
        me = fuzz.primitive_mesh(name, primitive)
        out = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", out)
        return out
    first = corners("first")
    np.testing.assert_array_equal(first, corners("second"))
    # in a fixed order: faces sorted by their vertex lists read from the lowest index
    me = fuzz.primitive_mesh("third", primitive)
    faces = [list(first[p.loop_start:p.loop_start + p.loop_total]) for p in me.polygons]
    keys = [f[f.index(min(f)):] + f[:f.index(min(f))] for f in faces]
    assert keys == sorted(keys)


def test_generator_covers_every_primitive_light_and_transform():
    params = [fuzz.scene_params(s) for s in COVERAGE_SEEDS]
    objects = [o for p in params for o in p["objects"]]
    lights = [light for p in params for light in p["lights"]]
    assert {o["primitive"] for o in objects} >= set(fuzz.PRIMITIVES)
    assert {o["transform"] for o in objects} >= {"plain", "nonuniform", "mirrored", "flattened", "tiny", "huge"}
    assert any(min(o["scale"]) < 0 for o in objects) and any(0.0 in o["scale"] for o in objects)
    assert {light["type"] for light in lights} == set(fuzz.LIGHT_TYPES)
    areas = [light for light in lights if light["type"] == "AREA"]
    assert {light["shape"] for light in areas} == set(fuzz.AREA_SHAPES)
    sizes = [light["size"] for light in areas if light["size"] > 0]
    assert min(sizes) < 1e-3 and max(sizes) > 10.0 and any(light["size"] == 0 for light in areas)
    spheres = [light for light in lights if light["type"] in ("POINT", "SPOT")]
    assert any(light["radius"] == 0 for light in spheres) and any(light["radius"] > 1.0 for light in spheres)
    spots = [light for light in lights if light["type"] == "SPOT"]
    assert min(s["spot_size"] for s in spots) < 0.5 and max(s["spot_size"] for s in spots) > 3.0
    assert any(s["spot_blend"] == 0 for s in spots) and any(0 < s["spot_blend"] < 1 for s in spots)
    suns = [light["angle"] for light in lights if light["type"] == "SUN"]
    assert 0.0 in suns and math.pi in suns and any(2.5 < a < math.pi for a in suns)
    assert {light["scale_kind"] for light in lights} == {"one", "uniform", "nonuniform", "mirrored", "zero"}
    counts = {len(p["lights"]) for p in params}
    assert counts == {0, 1, 2, 3, 4}
    cams = [p["camera"] for p in params]
    assert any(c["ortho"] for c in cams) and any(c["inside"] for c in cams) and any(not c["ortho"] for c in cams)
    assert any(p["floor"] is None for p in params) and any(p["floor"] and p["floor"]["rotation"][0] for p in params)


# ----------------------------------------------------------------------------------------------------------
# against Cycles
# ----------------------------------------------------------------------------------------------------------

# Fixed seeds for the default run: cheap scenes (one or two lights, a few objects, ~3-5 s each with both
# Cycles seeds at 64²) that differ in what they test. 0: torus, monkey and a squashed sphere under a small
# ellipse; 15: a mirrored torus under two spots (a 0.17 m sphere, a point); 19: orthographic camera, square
# light and a sharp sun; 9: five objects (mirrored, non-uniform, tiny) lit from 18° above the floor by a 0.5 m
# rectangle (smooth low-poly terminators).
FIXED_SEEDS = (0, 9, 15, 19)
# (technique, seed) pairs that fail today for a known reason: strict, so the test turns red once fixed.
KNOWN_FAILURES: dict = {
    ("SSM", 9): "SSM 0.178 at 64² over ~130 shadow pixels against 0.157 (0.49 before objects shadowed "
                "themselves, 0.24 before receivers lit through their own smooth triangles took the hard test): "
                "on the smooth mirrored monkey, a line of pixels lit where Cycles has them in shadow (PCSS and "
                "BACKPROJECTION leave most of that line lit too and stay within their bounds) and four pixels too "
                "dark beside it; not analysed further"}


@pytest.fixture(scope="module")
def fixed_rows():
    return {seed: {r.technique: r for r in fuzz.score_scene(seed, list(TECHNIQUES))} for seed in FIXED_SEEDS}


def _params():
    out = []
    for seed in FIXED_SEEDS:
        for technique in TECHNIQUES:
            reason = KNOWN_FAILURES.get((technique, seed))
            marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
            out.append(pytest.param(seed, technique, marks=marks, id=f"{seed}-{technique}"))
    return out


@pytest.mark.parametrize("seed,technique", _params())
def test_fixed_scene_within_bound(fixed_rows, seed, technique):
    r = fixed_rows[seed][technique]
    assert r.status == "ok", fuzz.format_row(r)


@pytest.mark.parametrize("seed", [pytest.param(s, marks=[pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[("PVSM", s)])]
                                  if ("PVSM", s) in KNOWN_FAILURES else []) for s in FIXED_SEEDS])
def test_pvsm_adaptive_fixed_scene_within_bound(seed):
    """PVSM's adaptive tiles (issue 13) on the same scenes, within PVSM's bound."""
    (r,) = fuzz.score_scene(seed, ["PVSM"], overrides={"pvsm_mode": "ADAPTIVE"})
    assert r.status == "ok", fuzz.format_row(r)


def _one_object_scene(primitive, scale, rotation, light, location=(0.0, 0.0, 1.0), transform="flattened"):
    return dict(seed=0, objects=[dict(name="Obj", primitive=primitive, transform=transform, location=list(location),
                                      rotation=list(rotation), scale=list(scale), smooth=True)],
                floor=dict(half_size=10.0, rotation=[0, 0, 0], z=0.0), lights=[light],
                camera=dict(ortho=False, location=[0.5, -4.0, 4.5], target=[0, 0, 0.3], lens=30.0, ortho_scale=5,
                            inside=None))


def _sun(angle, location=(1.0, -0.5, 4.0)):
    return dict(name="Sun", type="SUN", location=list(location), target=[0, 0, 0], scale=[1, 1, 1],
                scale_kind="one", distance=4.0, angle=angle, energy=3.0)


def _mae(params, technique="REFERENCE"):
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.measure import reference
    from penumbra.engine.measure.metrics import compare
    from penumbra.engine.render import pipeline
    scene = fuzz.build(params)
    ref = reference.cycles_visibility(scene, samples=fuzz.CYCLES_SAMPLES, width=64, height=64)
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    v = pipeline.render(snap, RenderSettings(technique=technique)).passes["Visibility"][..., 0]
    m = compare(v, ref.visibility, ref.mask)
    return m["mae_shadow"], m["n_shadow"]


@pytest.mark.parametrize("scale,rotation", [((0.8, 0.8, 0.0), (0, 0, 0)), ((0.8, 0.0, 0.8), (1.2, 0.3, 0.0))],
                         ids=["z0", "y0_rotated"])
def test_flattened_caster_shadows_as_in_cycles(scale, rotation):
    """Issue 10 item 4: a torus with one scale axis at 0 casts its shadow. REFERENCE measured 0.0058 and 0.0046
    against a Cycles noise floor of 0.002-0.003 (second seed); the bound leaves room for that noise twice."""
    mae, n = _mae(_one_object_scene("TORUS", scale, rotation, _sun(0.1)))
    assert n > 40
    assert mae < 0.012, mae


def test_smooth_low_poly_terminator_as_in_cycles():
    """A smooth-shaded, mirrored and non-uniformly scaled monkey (fuzz seed 9's) lit from low in front by a
    0.5 m rectangle: along its terminators the light is behind the triangles while their smooth normals
    still face it. Cycles lifts the shadow ray towards the smooth surface (Shadow Terminator Geometry Offset;
    with it at 0 those pixels go black), and a ray still aimed into the surface is stopped by it. Penumbra
    leaves the G-buffer's lifted point to the shadow-map lookup and compares a light behind the triangle
    without the tangent-plane rule: REFERENCE 0.1385 -> 0.0086 at 64² (Cycles' noise floor about 0.002);
    the bound leaves REFERENCE's own spread on the other fixed scenes."""
    params = dict(seed=0, objects=[dict(name="Monkey", primitive="MONKEY", transform="mirrored", smooth=True,
                                        location=[-0.0427, 0.1950, 1.2974], rotation=[-0.2551, -0.0871, -0.0943],
                                        scale=[1.1510, -1.6803, 1.6487])],
                  floor=dict(half_size=15.0, rotation=[0, 0, 0], z=-0.242),
                  lights=[dict(name="Key", type="AREA", location=[-0.6242, -3.4541, 0.9129],
                               target=[-0.2724, -0.2554, 1.3073], scale=[1, 1, 1], scale_kind="one",
                               distance=3.524, shape="RECTANGLE", size=0.5027, size_y=0.3983, energy=1487.0)],
                  camera=dict(ortho=False, location=[-3.294, -1.407, 2.344], target=[0.433, -0.705, 0.646],
                              lens=30.61, ortho_scale=3.45, inside=None))
    mae, n = _mae(params)
    assert n > 40
    assert mae < 0.02, mae


def test_failure_class_names_what_the_scale_changes():
    """'scaled light' only where the object scale changes Cycles' light beyond turning it: a point light's
    scale and a sun's non-uniform or mirrored scale do not (fuzz 8461 renders the same Cycles image with its
    point light's scale at 1: that failure is a light under the floor, its sphere reaching above it)."""
    def classes(light, floor=None):
        params = _one_object_scene("CUBE", (0.5, 0.5, 0.5), (0, 0, 0), light, transform="plain")
        params["floor"] = floor or params["floor"]
        return fuzz.failure_class(params, []).split(", ")
    assert "scaled light" not in classes(_scaled_light("POINT", (1.0, 0.3, 2.0), radius=0.3))
    assert "scaled light" not in classes({**_sun(0.3), "scale": [2.0, -0.3, 1.0]})
    assert "scaled light" in classes({**_sun(0.3), "scale": [2.0, 0.3, 0.0]})
    assert "scaled light" in classes(_scaled_light("SPOT", (1.6, 0.5, 0.8), radius=0.0))
    assert "scaled light" in classes(_scaled_light("AREA", (1.0, 1.0, 0.0)))
    assert "scaled light" not in classes(_scaled_light("AREA", (-1.0, 1.0, 1.0)))
    under = _scaled_light("POINT", (1.0, 1.0, 1.0), radius=0.59, location=[5.39, -0.06, 1.93])
    tilted = dict(half_size=11.3, rotation=[-0.4419, -0.4782, 0.0], z=-0.186)      # fuzz 8461's floor
    assert "light below the floor" in classes(under, tilted)
    assert "light below the floor" not in classes({**under, "radius": 0.5}, tilted)   # all of it below
    assert "light sphere holds receivers" in classes({**under, "location": [0.3, 0.0, 1.0]})


def _scaled_light(kind, scale, **kw):
    light = dict(name="Light", type=kind, location=[1.0, -0.6, 3.2], target=[0.0, 0.0, 0.0], scale=list(scale),
                 scale_kind="nonuniform", distance=3.4, energy=1500.0)
    light.update(kw)
    return light


SCALED_LIGHTS = {
    # Cycles ignores a point light's object scale (kernel/light/point.h reads only its position and radius)
    "point_1_0.3_2": _scaled_light("POINT", (1.0, 0.3, 2.0), radius=0.3, soft_falloff=True),
    # the cone stretched by scale x (y) over scale z
    "spot_1.6_0.5_0.8": _scaled_light("SPOT", (1.6, 0.5, 0.8), radius=0.2, soft_falloff=True,
                                      spot_size=math.radians(50), spot_blend=0.3),
    # size × |scale| per axis; the mirrored X leaves the rectangle and its emission side as they are
    "area_-1.5_0.7_1": _scaled_light("AREA", (-1.5, 0.7, 1.0), shape="RECTANGLE", size=0.8, size_y=0.5,
                                     energy=800.0),
}


@pytest.mark.parametrize("technique", ["REFERENCE", "PCSS"])
@pytest.mark.parametrize("light", list(SCALED_LIGHTS))
def test_scaled_light_shadows_as_in_cycles(light, technique):
    """Issue 10 item 5: a torus over the floor under a light with a non-uniform (or mirrored) object scale,
    within the fuzz's bound: the scaled light's shape, which REFERENCE samples and PCSS sizes its penumbra by,
    is the one Cycles renders. Measured at 64²: REFERENCE 0.026 / 0.015 / 0.023, PCSS 0.033 / 0.037 / 0.059
    (bounds 0.047-0.051 and 0.167-0.170 with Cycles' noise floor)."""
    params = _one_object_scene("TORUS", (0.6, 0.6, 0.6), (0.4, 0.2, 0.0), SCALED_LIGHTS[light],
                               location=(0.0, 0.0, 0.7), transform="plain")
    m, limit = fuzz.shadow_score(params, technique)
    assert m["n_shadow"] > 80
    assert m["mae_shadow"] < limit, (m["mae_shadow"], limit)


def test_zero_scale_spot_beside_another_light_as_in_cycles():
    """A spot with a zero Z scale and a radius beside an area light: Cycles' light tree picks the spot so rarely
    that a render of both at once holds its light as fireflies (fuzz 26029, 27032), while each light alone
    converges; the reference renders them one at a time. Measured at 64², 256 spp: Unshadowed error 0.037
    against the two lights rendered at once (within a bound that the fireflies' noise floor loosens to 0.062),
    0.0002 against the sum; REFERENCE 0.040 / 0.008. The unshadowed light is held to the model error alone."""
    objs = [fuzz.hand_object("Ball", "UV_SPHERE", (0.0, 0.0, 0.5), (0.4, 0.4, 0.4), smooth=True),
            fuzz.hand_object("Box", "CUBE", (-0.9, 0.6, 0.25), (0.25, 0.25, 0.25))]
    lights = [fuzz.hand_light("Area", "AREA", (0.3, -0.5, 3.0), (0.0, 0.0, 0.0), 300.0, shape="SQUARE", size=1.0,
                              size_y=1.0),
              fuzz.hand_light("Spot", "SPOT", (1.8, 0.8, 2.2), (0.0, 0.0, 0.0), 800.0, scale=(1.0, 1.0, 0.0),
                              radius=0.2, soft_falloff=True, spot_size=math.radians(60), spot_blend=0.2)]
    params = fuzz.hand_scene(objs, lights, fuzz.hand_camera((0.0, -4.0, 3.0), (0.0, 0.0, 0.3)), floor_half_size=4.0)
    u, _ = fuzz.unshadowed_score(params)
    assert u < fuzz.UNSHADOWED_ABS, u
    m, limit = fuzz.shadow_score(params, "REFERENCE")
    assert m["n_shadow"] > 100
    assert m["mae_shadow"] < limit, (m["mae_shadow"], limit)


def test_wide_light_over_a_floor_to_the_horizon_within_bound():
    """Fuzz 29050: a 0.83 m soft point light 4 m over a floor that reaches the horizon, so its single view is
    clamped and cube faces take the pixels past its window. Near the window's edge the sample maps REFERENCE
    renders from points of the light missed floor pixels that a cylinder shades (off 120 of 256 maps, counted
    lit): the single view now keeps only what a view from every point of the light holds
    (pipeline._sample_margin). 0.070 before (bound 0.043), 0.034 after."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(29050), "REFERENCE")
    assert m["n_shadow"] > 200
    assert m["mae_shadow"] < limit, (m["mae_shadow"], limit)


@pytest.mark.parametrize("angle", [3.0, math.pi], ids=["3rad", "180deg"])
def test_wide_sun_visibility_as_in_cycles(angle):
    """Issue 10 item 5: a ball over the floor under a sun of 3 rad and 180°. REFERENCE samples the cone uniformly
    with cosine weights: measured 0.0096 / 0.0098 (before: 0.047 / 0.050 with the disk of tan θ; Cycles'
    noise floor 0.0037); 0.015 leaves Cycles' noise and REFERENCE's 64 samples their share."""
    params = _one_object_scene("UV_SPHERE", (0.5, 0.5, 0.5), (0, 0, 0), _sun(angle, (1.5, -1.0, 4.0)),
                               location=(0.0, 0.0, 0.9), transform="plain")
    params["camera"].update(location=[0.5, -5.0, 4.0], target=[0.0, 0.0, 0.3])
    mae, n = _mae(params)
    assert n > 500
    assert mae < 0.015, mae


@pytest.fixture(scope="module")
def far_side_of_a_ball():
    """A big flat-shaded ball on a floor under a 2.9 rad sun whose centre lies behind it as the camera sees it:
    the visible side faces away from the sun's centre, yet most of the sun is above its faces (the fuzz class
    of seed 8011). Nothing but the ball itself lies between those faces and the sun, so Cycles has them lit.
    The sun object sits inside the ball: where a sun is placed does not matter to Cycles, but its map's depths
    are measured from there."""
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.measure import reference
    params = _one_object_scene("UV_SPHERE", (1.5, 1.5, 1.5), (0, 0, 0), _sun(2.9, (-0.03, 0.4, 0.06)),
                               location=(0.0, 0.0, 0.0), transform="plain")
    params["objects"][0]["smooth"] = False
    params["floor"] = dict(half_size=4.0, rotation=[0, 0, 0], z=-1.5)     # a receiver that faces the sun
    params["camera"].update(location=[0.6, -6.0, 1.2], target=[0.0, 0.0, 0.0])
    scene = fuzz.build(params)
    ref = reference.cycles_visibility(scene, samples=fuzz.CYCLES_SAMPLES, width=64, height=64)
    return extract(bpy.context.evaluated_depsgraph_get(), scene), ref


@pytest.mark.heavy
@pytest.mark.parametrize("technique", TECHNIQUES)
def test_wide_sun_lights_the_far_side_of_a_convex_object(far_side_of_a_ball, technique):
    """Receivers facing away from a wide sun's centre compare with no texel of its map (its tangent-plane rule);
    a sun's orthographic depths are measured from the sun object's location and run negative for whatever
    lies behind it, and the old "nothing counts" depth of 0 made those texels blockers: HARD, PCF, PCSS and
    PVSM had the ball's visible side black (mae_shadow 1.0 on fuzz seed 8011). SPSM had 67 % of these pixels
    black from its own plain depth test until it took HARD's receiver for faces turned from the centre."""
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.render import pipeline
    snap, ref = far_side_of_a_ball
    away = ref.mask & (ref.visibility >= 0.99)
    assert away.sum() > 400
    v = pipeline.render(snap, RenderSettings(technique=technique)).passes["Visibility"][..., 0]
    dark = float(np.mean(v[away] < 0.5))      # black, not a penumbra estimate off by a little
    print(technique, "share of Cycles-lit pixels below 0.5:", dark)
    assert dark <= 0.01


def test_hard_techniques_are_held_to_the_light_centres_hard_shadow():
    """HARD, PCF and SPSM stand for a light by its centre: their bound is the error of Cycles' shadow of the
    lights shrunk to their centres, plus HARD_ABS (fuzz.hard_bound). Under wide suns that error is the soft
    shadow's own: fuzz 29005 (a plane under a 2.1 rad sun, a 0.37 rad sun and a spot) HARD 0.26, over the
    0.24 the old bound read off a percentile allowed, and within this one. Under a small light the bound is
    tight: on seed 0 HARD scores 0.011 against a bound of 0.048, and a 32-texel map (its shadow edges pixels
    off) 0.083, which fails it (the old bound, 0.25, let it pass)."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(29005), "HARD")
    print("29005 HARD", m["mae_shadow"], "bound", limit)
    assert m["mae_shadow"] > fuzz.BOUND_ABS["HARD"] and m["mae_shadow"] <= limit
    sharp, limit = fuzz.shadow_score(fuzz.scene_params(0), "HARD")
    coarse, same = fuzz.shadow_score(fuzz.scene_params(0), "HARD", overrides={"shadow_map_size": 32})
    print("seed 0 HARD", sharp["mae_shadow"], "bound", limit, "with 32 texels", coarse["mae_shadow"], "bound", same)
    assert sharp["mae_shadow"] <= limit < 0.1
    assert coarse["mae_shadow"] > same


@pytest.mark.heavy
@pytest.mark.parametrize("seed,technique", [(28164, "HARD"), (29093, "REFERENCE")])
def test_shadows_within_a_texel_of_a_grazing_receiver_within_bound(seed, technique):
    """The depth bias's slope term (glsl/common/light_view.glsl SLOPE_BIAS) at 1 per unit of tan θ hid real
    shadows near grazing receivers: 28164 (a flattened cube through a ball under a 2 mm point light) HARD 0.121,
    a band of the ball lit where Cycles' centre shadow has it dark; 29093 (a 3.7 mm spot with a 172° cone)
    REFERENCE 0.055, its hard edges a texel short. With 0.1 and a normal offset of 0.25 texels: 0.037 and 0.038,
    each within its bound."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(seed), technique)
    print(seed, technique, m["mae_shadow"], "bound", limit)
    assert m["mae_shadow"] <= limit


@pytest.mark.heavy
@pytest.mark.parametrize("facets", [True, False])
def test_a_creases_far_face_within_the_bias_shadows_as_in_cycles(facets):
    """Fuzz 1103, the crease class: the camera inside a room, 0.3 m from a flat-shaded Suzanne lit at n·l ≈ 0.1
    by a 0.9 m soft point light 3 m away. Where her faces meet at concave creases, the far face rises over the
    near one by less than the sample maps' depth bias (1 cm texels), so each map left it lit; Cycles has it
    dark (V 0 where REFERENCE gave 0.4-0.9). The facet test (averaged_facets; light_view.glsl facet_separates)
    takes the plane of the triangle a texel holds: 0.107 -> 0.051 against a bound of 0.078. Without it (the
    default, for its cost) the scene stays over its bound: the test that the facet test is what holds it."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(1103), "REFERENCE", overrides={"averaged_facets": facets})
    print("facets", facets, m["mae_shadow"], "bound", limit)
    assert (m["mae_shadow"] <= limit) == facets


@pytest.mark.parametrize("technique", ["HARD", "SPSM"])
def test_lifted_shadow_ray_starts_lie_inside_the_view(technique):
    """Fuzz 29243: a smooth cylinder's 32-gon cap lit from behind its plane by a sun 8° above it, through its
    shading normals. Its shadow rays leave from points lifted up to 0.2 m off the cap (the terminator offset,
    as Cycles lifts them), and Cycles finds the tilted ground in their way. The sun's window was fitted to the
    lit pixels alone, the lifted starts fell outside it and counted as lit: HARD and SPSM 0.061 against bounds
    of 0.034. With the starts in the lit box (render/lit_bounds.comp): 0.0036."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(29243), technique)
    print(technique, m["mae_shadow"], "bound", limit)
    assert m["mae_shadow"] <= limit


def test_pixels_we_send_no_light_are_not_scored_for_visibility():
    """Fuzz 30011: a sphere and a cube sunk into the floor under a 1.3 mm spot. At four pixels on the crease the
    centre ray hits the back of the sphere (or cube) just above the floor: we send no light there (V is 0/0, written
    as 1). At three of them one or two of Cycles' 256 samples land on the lit floor beside it (its unshadowed 0.4 %
    of the floor's, shadowed 0, so V 0); at the fourth the centre lies on the crease line itself and a third of
    Cycles' samples find the floor. They made REFERENCE's mae_shadow 0.049 against its bound of 0.046; scored where
    both renders send light (fuzz.scored_mask), 0.019. The pixels left out are exactly those we leave dark, and the
    Unshadowed check still judges their light."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(30011), "REFERENCE")
    print("30011 REFERENCE", m["mae_shadow"], "bound", limit, "pixels", m["n_mask"])
    assert m["mae_shadow"] <= limit


def test_scored_mask_is_cycles_mask_where_we_send_light():
    ref = type("Ref", (), {"mask": np.array([[True, True], [False, True]])})()
    cyc = fuzz.SceneReference(ref, {}, 0.0, 0.0)
    unshadowed = np.zeros((2, 2, 4), np.float32)
    unshadowed[0, 0, :3] = 0.5
    unshadowed[1, 0, :3] = 0.5
    unshadowed[1, 1, 1] = 1e-6
    result = type("Result", (), {"passes": {"Unshadowed": unshadowed}})()
    assert fuzz.scored_mask(result, cyc).tolist() == [[True, False], [False, True]]


# ----------------------------------------------------------------------------------------------------------
# the long sweep
# ----------------------------------------------------------------------------------------------------------

SWEEP_SEEDS = range(1000, 1200)
# Every technique fails somewhere in 200 random scenes today, for these known reasons (see the fuzz report in
# issue 10): strict, so a technique's test turns red when its last failure is fixed and the marker must go.
SWEEP_XFAIL = ("known classes (issue 10's notes): REFERENCE - a crease next to a camera inside a room (1103: 0.107 "
               "against 0.078 over 48 shadow pixels under fuzz.scored_mask, within it with averaged_facets on, "
               "tests/test_fuzz.py test_a_creases_far_face_within_the_bias_shadows_as_in_cycles; 1098 and "
               "1169, soft-falloff balls holding receivers, pass since session 26); the others besides: lights "
               "whose ball holds receivers, wide suns, flattened and edge-on casters")


@pytest.fixture(scope="module")
def sweep_rows():
    return fuzz.run(SWEEP_SEEDS.start, len(SWEEP_SEEDS))


@pytest.mark.slow
@pytest.mark.parametrize("technique", [pytest.param(t, marks=pytest.mark.xfail(strict=True, reason=SWEEP_XFAIL))
                                       for t in TECHNIQUES])
def test_sweep_no_scene_over_its_bound(sweep_rows, technique):
    bad = [r for r in sweep_rows if r.technique == technique and r.status != "ok"]
    assert not bad, f"{len(bad)} scene(s) over the bound:\n" + "\n".join(fuzz.format_row(r) for r in bad[:20])


def test_params_survive_json():
    """Saved failures carry their parameters as JSON: they must rebuild the same scene."""
    import json
    p = fuzz.scene_params(11)
    assert json.loads(json.dumps(p)) == p
    q = copy.deepcopy(p)
    assert fuzz.describe(q) == fuzz.describe(p)


def test_failure_class_names_a_light_whose_emitter_crosses_a_caster():
    """From the extracted triangles: a sphere or area light whose emitter reaches a caster's surface (fuzz
    18024 and 18063, where every soft technique and REFERENCE missed: Cycles blocks the emitter's points
    beyond the caster's wall). Not a light clear of every caster, not a sun, not a caster that casts no shadow."""
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.snapshot import POINT, SUN, Light
    from penumbra.engine.measure import stress
    box = stress.box((-1, -1, 0), (1, 1, 1))

    def crossing(light, caster=True):
        snap = stress.assemble([("Box", box, caster, True)], [light], stress.camera(), "crossing")
        return fuzz.crossing_lights(snap)

    def lamp(radius):
        return Light("Lamp", POINT, stress.look_at((0.0, 0.0, 1.3), (0.0, 0.0, 0.0)), np.ones(3), 100.0, radius=radius)
    assert crossing(lamp(0.5)) == ["Lamp"]
    assert crossing(lamp(0.2)) == []
    assert crossing(lamp(0.5), caster=False) == []
    assert crossing(stress.area_light((0.0, 0.0, 1.5), size=1.0)) == ["Area"]      # half diagonal 0.71 > 0.5
    assert crossing(stress.area_light((0.0, 0.0, 1.9), size=1.0)) == []
    assert crossing(Light("Sun", SUN, stress.look_at((0.0, 0.0, 1.3), (0.0, 0.0, 0.0)), np.ones(3), 3.0,
                          angle=3.0)) == []
    for seed in (18024, 18063):
        params = fuzz.scene_params(seed)
        scene = fuzz.build(params, (16, 16))
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
        assert "light crosses a caster" in fuzz.failure_class(params, [], snap).split(", ")


def test_failure_class_names_a_caster_the_light_centre_sees_edge_on():
    """From the extracted triangles: a caster with most of its area within about 6° of the light centre's rays
    (fuzz 30065: a 10 m plane 3.4° off edge-on under a 112° sun, where PCSS, SSM and PVSM light the floor
    beside it). Not the same plane turned 45° or face-on, not the floor at the light's level."""
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.snapshot import SUN, Light
    from penumbra.engine.measure import scenes, stress

    def edge_on(tilt_degrees, name="Sheet"):
        t = math.radians(tilt_degrees)          # 0: the sheet's plane holds the sun's rays (straight down)
        u, v = np.array([1.0, 0.0, 0.0]), np.array([0.0, math.sin(t), math.cos(t)])
        c = np.array([0.0, 0.0, 1.5])
        corners = [c - u - v, c + u - v, c + u + v, c - u + v]
        sheet = np.array([[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]])
        sun = Light("Sun", SUN, stress.look_at((0.0, 0.0, 5.0), (0.0, 0.0, 0.0)), np.ones(3), 3.0, angle=2.0)
        snap = stress.assemble([(name, sheet, True, True)], [sun], stress.camera(), "edge-on")
        return fuzz.edge_on_casters(snap)
    assert edge_on(0.0) == ["Sheet"]
    assert edge_on(3.4) == ["Sheet"]
    assert edge_on(45.0) == []
    assert edge_on(90.0) == []
    assert edge_on(0.0, name=scenes.GROUND_NAME) == []
    params = fuzz.scene_params(30065)
    scene = fuzz.build(params, (16, 16))        # before the depsgraph is taken
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert "edge-on caster" in fuzz.failure_class(params, [], snap).split(", ")


def test_failure_class_names_a_light_or_camera_inside_an_open_caster():
    """From the extracted triangles: a lamp or the camera inside a caster that is not closed (fuzz 30185, a lamp
    inside a 5x Suzanne; 30091, the camera inside a 10x one), where light leaves only by the openings. Not a
    point beside the open caster, and not one inside a closed caster (the pipeline decides that one exactly)."""
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.snapshot import POINT, Light
    from penumbra.engine.measure import stress
    closed = stress.box((-1, -1, 0), (1, 1, 2))
    lid = np.flatnonzero(np.abs(closed[:, :, 2] - 2.0).max(axis=1) <= 1e-9)
    open_box = np.delete(closed, lid[:1], axis=0)       # one of its lid's two triangles gone

    def inside(mesh, at):
        lamp = Light("Lamp", POINT, stress.look_at(at, (0.0, 0.0, 0.0)), np.ones(3), 100.0, radius=0.1)
        snap = stress.assemble([("Box", mesh, True, True)], [lamp], stress.camera(), "shell")
        return fuzz.inside_open_casters(snap)
    assert len(open_box) == len(closed) - 1
    assert inside(open_box, (0.2, 0.1, 0.7)) == ["light"]
    assert inside(open_box, (3.0, 0.1, 0.7)) == []
    assert inside(closed, (0.2, 0.1, 0.7)) == []
    for seed, what in ((30185, "light"), (30091, "camera")):
        params = fuzz.scene_params(seed)
        scene = fuzz.build(params, (16, 16))
        snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
        assert f"{what} inside an open caster" in fuzz.failure_class(params, [], snap).split(", ")


def test_fireflies_in_the_reference_are_told_from_hard_edges():
    """A light Cycles' light tree picks with a tiny probability comes out as fireflies that each seed puts in
    other pixels (fuzz 27032): the failure report names that class. A hard light edge, or a small lit patch,
    is the same in both seeds and is not one."""
    rng = np.random.default_rng(3)
    mask = np.ones((32, 32), bool)
    base = np.zeros((32, 32))
    base[:, 16:] = 1.0                      # a hard edge: both seeds alike
    base[3, 3] = 5.0                        # a small bright patch: both seeds alike
    assert fuzz.firefly_share(base, base.copy(), mask) == 0.0
    a, b = base + 0.01 * rng.random((32, 32)), base + 0.01 * rng.random((32, 32))
    assert fuzz.firefly_share(a, b, mask) < 0.01
    a[10, 20] += 200.0                      # one seed's fireflies carry a light the other misses there
    b[25, 5] += 200.0
    share = fuzz.firefly_share(a, b, mask)
    assert share == pytest.approx(400.0 / (a.sum() + b.sum()), rel=0.05) and share > fuzz.FIREFLY_SHARE


def test_summary_reports_failures_error_and_frame_time_per_technique():
    """The sweep's summary puts each technique's error beside its frame time (the user's error against run
    time), and counts the failures by class; a crashed render (no time) leaves the medians alone."""
    def row(seed, technique, mae, ms, status="ok", cls=""):
        return fuzz.Row(seed, "s", technique, mae, 100, 0.1, 0.0, 0.0, 0.02, ms, status, cls)
    rows = [row(1, "HARD", 0.01, 10.0), row(2, "HARD", 0.03, 30.0), row(3, "HARD", 0.5, 20.0, "OVER", "wide sun"),
            row(1, "SSM", 0.02, 100.0), row(2, "SSM", math.nan, math.nan, "CRASH", "boom")]
    text = fuzz.summary(rows).splitlines()
    assert text[0].split() == ["HARD", "1/3", "over", "bound;", "median", "mae_shadow", "0.0300,", "90th", "pct",
                               "0.4060;", "frame", "median", "20", "ms,", "90th", "pct", "28", "ms"]
    assert text[1].split() == ["1", "wide", "sun"]
    assert "1/2 over bound" in text[2] and "median mae_shadow 0.0200" in text[2] and "frame median 100 ms" in text[2]
    assert text[3].split() == ["1", "boom"]
