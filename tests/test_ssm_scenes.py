"""SSM on the classes of random scene it used to fail (issue 10; fuzz seeds 5000-5039 and 6000-6039), each a
small hand-made scene in the random-scene generator's own format, scored against Cycles with the fuzz's
SSM bound. Both failed through the paper's occluder/receiver split (an object never shadowed itself) and
its one receiver map rasterised from the light:
- an enclosing shell lit from outside (fuzz 6003, 6020, 6028: a 5-9 m cube around the scene; 6022, 5017:
  the camera in a room): Cycles has everything inside dark, SSM lit it (the walls did not shadow their own
  object, and the floor inside sat between the shell's top and bottom in the receiver map);
- an object shadowing another part of itself (fixed seed 9's monkey; here a torus standing upright, whose
  upper arc shadows the inside of its lower arc).
Later classes (a sun below its caster, a shell around the camera under a wide sun, a sliver light over a
wide view) say what failed beside each scene.
Cycles references are cached."""
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.measure import fuzz, reference, scenes  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402

RES = (64, 64)
SPP = 256


_object, _light = fuzz.hand_object, fuzz.hand_light


def _camera(location, target, lens=24.0, inside=None):
    return fuzz.hand_camera(location, target, lens, ortho_scale=5.0, inside=inside)


SCENES = {
    # A closed 6 × 6 × 4 m box with the camera, a ball and a point light inside, the floor running through
    # it, and a sun outside: the sun lights nothing the camera sees (Cycles: its shadow rays leave through
    # the walls or the roof), the point light lights the inside with the ball's shadow.
    "shell_lit_from_outside": dict(
        seed=-1,
        objects=[_object("Room", "CUBE", (0.0, 0.0, 1.2), (3.0, 3.0, 2.0), transform="room"),
                 _object("Ball", "ICO_SPHERE", (0.6, 0.4, 0.5), (0.45, 0.45, 0.45))],
        floor=dict(half_size=10.0, rotation=[0.0, 0.0, 0.0], z=0.0),
        lights=[_light("Sun", "SUN", (3.0, 2.0, 8.0), (0.0, 0.0, 0.0), 3.0, angle=0.2),
                _light("Lamp", "POINT", (-0.8, -0.6, 2.4), (0.0, 0.0, 0.0), 400.0, radius=0.2,
                       soft_falloff=True)],
        camera=_camera((2.2, -2.2, 1.9), (-0.5, 0.5, 0.4), inside="Room")),
    # A torus standing upright under a small square light straight above, no floor: the inside of its lower
    # arc lies in the shadow of its upper arc, so every shadow pixel is the object shadowing itself.
    "torus_shadows_itself": dict(
        seed=-2,
        objects=[_object("Ring", "TORUS", (0.0, 0.0, 1.0), (1.0, 1.0, 1.0), rotation=(math.pi / 2, 0.0, 0.3))],
        floor=None,
        lights=[_light("Light", "AREA", (0.2, 0.1, 5.0), (0.0, 0.0, 0.0), 1000.0, shape="SQUARE", size=0.5,
                       size_y=0.5)],
        camera=_camera((0.3, -2.6, 2.2), (0.0, 0.0, 0.8), lens=35.0)),
    # A sun whose object sits below the box it shadows (fuzz 8010, 8015, 8107: huge casters, or a sun placed
    # inside the scene): a sun's light frame sits at the object, so the box lies at negative depth, which
    # the occluder maps read as empty texels. Before the SSM view moved its eye behind the casters: the
    # box's shadow on the floor missing, mae_shadow 0.78; after: 0.009.
    "sun_below_its_caster": dict(
        seed=-3,
        objects=[_object("Box", "CUBE", (0.0, 0.0, 1.6), (1.0, 1.0, 0.4))],
        floor=dict(half_size=6.0, rotation=[0.0, 0.0, 0.0], z=0.0),
        lights=[_light("Sun", "SUN", (0.25, 0.15, 0.5), (0.0, 0.0, 0.0), 3.0, angle=0.1)],
        camera=_camera((0.5, -4.0, 3.5), (0.0, 0.0, 0.3), lens=24.0)),
    # The camera inside a closed ball 12 m across under a sun 3 rad wide, a lamp and a smaller ball inside with
    # it (fuzz 8005, 8010, 8015, 8107): the sun lights nothing the camera sees. From the inside most of a wide
    # sun's rays leave the shell under the silhouette of its half turned to the sun, which only the
    # back-face map holds, and the two maps merge by maximum (§3.5): SSM let the sun through.
    "ball_around_camera_under_wide_sun": dict(
        seed=-4,
        objects=[_object("Shell", "UV_SPHERE", (0.0, 0.0, 1.0), (6.0, 6.0, 6.0)),
                 _object("Ball", "ICO_SPHERE", (0.5, 0.8, -1.2), (0.6, 0.6, 0.6))],
        floor=None,
        lights=[_light("Sun", "SUN", (-6.0, -5.0, 4.0), (0.0, 0.0, 0.5), 6.0, angle=3.0),
                _light("Lamp", "POINT", (-0.8, -0.4, 2.5), (0.0, 0.0, 0.0), 900.0, radius=0.3,
                       soft_falloff=True)],
        camera=_camera((0.3, -2.0, 3.5), (0.2, 0.6, -2.5), lens=30.0)),
    # A sliver of a rectangle light (0.6 × 0.05 m) 1.6 m over a floor, three casters around it 30-60° off its
    # axis (fuzz 9001: a 0.30 × 0.035 m light): a view that wide with texels of the light's aspect ratio
    # (§3.2) had 22 × 256 of them, each 12 times longer across the sliver than along it, and the receivers'
    # slope-scaled bias and normal offset, taken from the texel's longer side, kept the casters from
    # shadowing the floor. ssm_texels LIGHT: mae_shadow 0.66; SQUARE (the default): 0.033.
    "sliver_light_wide_view": dict(
        seed=-5,
        objects=[_object("BoxA", "CUBE", (1.6, 0.3, 0.8), (0.25, 0.25, 0.25), rotation=(0.0, 0.0, 0.4)),
                 _object("BoxB", "CUBE", (-0.9, -1.4, 0.9), (0.2, 0.35, 0.2), rotation=(0.3, 0.0, 0.0)),
                 _object("Ball", "UV_SPHERE", (-0.4, 1.3, 0.7), (0.3, 0.3, 0.3))],
        floor=dict(half_size=12.0, rotation=[0.0, 0.0, 0.0], z=0.0),
        lights=[_light("Sliver", "AREA", (0.0, 0.0, 1.6), (0.05, 0.02, 0.0), 300.0, shape="RECTANGLE",
                       size=0.6, size_y=0.05)],
        camera=_camera((0.5, -5.5, 7.5), (0.0, 0.0, 0.0), lens=24.0)),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_ssm_within_its_fuzz_bound(name):
    """mae_shadow within the bound every random scene gets (fuzz.bound: the scene's Cycles noise floor + 0.14
    + 2 edge pixels). Before the receiver's tangent plane replaced the object split, and the camera's receiver
    pixels the rasterised receiver map: shell 0.41, torus 1.0 (every self-shadowed pixel lit), at 64²; after:
    0.012 and 0.12 (the torus's ends, where one light texel sees three receivers: see techniques/ssm.py)."""
    m, bound = fuzz.shadow_score(SCENES[name], "SSM", RES, SPP)
    print(f"{name}: mae_shadow {m['mae_shadow']:.4f} over {m['n_shadow']} px, bound {bound:.4f}")
    assert m["n_shadow"] > 300
    assert m["mae_shadow"] <= bound, f"{name}: mae_shadow {m['mae_shadow']:.4f} > {bound:.4f}"


def test_cube_faces_lit_by_part_of_the_light_are_not_shadowed_by_their_own_cube():
    """Now that an object may shadow itself, its own micro-patches must still leave the faces alone that
    the light reaches (tests/test_grazing.py's criterion for the shadow-map techniques, on its `cube`
    scene): at most 1 % of the pixels Cycles has fully lit may fall below 0.9. Before (object split, receiver
    map rasterised from the light): 9.7 %, after: 0.08 %."""
    sc = scenes.build("cube", resolution=(96, 96))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=SPP)
    v = pipeline.render(snap, RenderSettings(technique="SSM")).passes["Visibility"][..., 0]
    lit = ref.mask & (ref.visibility >= 0.99)
    assert lit.sum() > 2000
    dark = float(np.mean(v[lit] < 0.9))
    print("SSM share of Cycles-lit pixels below 0.9:", dark)
    assert dark <= 0.01


@pytest.mark.heavy
@pytest.mark.parametrize("angle", [2.5, 3.1])
def test_wide_sun_occlusion_weighs_the_solid_angle(angle):
    """A ball on the floor under a sun 2.5 and 3.1 rad wide (64², Cycles 256 spp; fuzz 8015, 8107's suns).
    A sun's micro-patches hid their share of the square of direction tangents, each tangent counted alike,
    while per unit of tangent area a direction θ off the axis carries cos⁴θ of the irradiance (solid angle
    cos³θ, receiver cosine cosθ): mae_shadow 0.076 and 0.096
    (PCSS 0.067 and 0.073). Weighted by the parallel-rectangle form factor at unit height: 0.048 and 0.049,
    the criterion BACKPROJECTION's wide-sun test holds it to."""
    from penumbra.tests.test_spsm import wide_sun_ball_errors
    mae = wide_sun_ball_errors(angle, ("PCSS", "SSM"))
    assert mae["SSM"] <= 0.8 * mae["PCSS"]


# Thin casters (a bar and a pole) under the round lights SSM used to treat as their bounding rectangles: a disk
# and an ellipse area light, a 0.6 rad sun. A thin caster's penumbra hides a sliver across the light, a share
# of the disk up to 4/π times its share of the square, so the square lightened every such penumbra.
_THIN_CASTERS = [_object("Bar", "CUBE", (0.0, 0.0, 0.9), (0.9, 0.03, 0.03), rotation=(0.0, 0.0, 0.3)),
                 _object("Pole", "CYLINDER", (-0.8, 0.9, 0.6), (0.04, 0.04, 0.6))]
_ROUND_LIGHTS = {
    "disk": _light("Disk", "AREA", (0.2, 0.1, 2.2), (0.0, 0.0, 0.0), 600.0, shape="DISK", size=1.4, size_y=1.4),
    "ellipse": _light("Ellipse", "AREA", (0.2, 0.1, 2.2), (0.0, 0.0, 0.0), 600.0, shape="ELLIPSE", size=1.8,
                      size_y=0.8),
    "sun": _light("Sun", "SUN", (0.5, 0.3, 2.0), (0.0, 0.0, 0.0), 4.0, angle=0.6),
}


@pytest.mark.parametrize("light", list(_ROUND_LIGHTS))
def test_thin_casters_under_a_round_light_as_close_as_the_reference(light):
    """SSM's micro-patches hide shares of the round light itself (glsl/ssm/patch.glsl light_share), not of its
    bounding rectangle: its mae_shadow (64², Cycles 256 spp) at most REFERENCE's at 64 samples.
    With the rectangle: disk 0.0168, ellipse 0.0175, sun 0.0158 against REFERENCE's 0.0132, 0.0150, 0.0140;
    with the disk: 0.0098, 0.0108, 0.0094."""
    scene = dict(seed=-11 - list(_ROUND_LIGHTS).index(light), objects=_THIN_CASTERS,
                 floor=dict(half_size=8.0, rotation=[0.0, 0.0, 0.0], z=0.0), lights=[_ROUND_LIGHTS[light]],
                 camera=_camera((0.4, -3.6, 3.2), (0.0, 0.2, 0.2), lens=30.0))
    ssm, _ = fuzz.shadow_score(scene, "SSM", RES, SPP)
    ref, _ = fuzz.shadow_score(scene, "REFERENCE", RES, SPP, overrides={"averaged_light_samples": 64})
    print(f"{light}: SSM {ssm['mae_shadow']:.4f}, REFERENCE {ref['mae_shadow']:.4f} over {ssm['n_shadow']} px")
    assert ssm["n_shadow"] > 100
    assert ssm["mae_shadow"] <= ref["mae_shadow"]


def _point_light_cutting_a_ball():
    """A ball, a flattened sheet through it and a post under a 2 mm point light (fuzz 28164's class)."""
    return fuzz.hand_scene(
        [_object("Ball", "ICO_SPHERE", (0.0, 0.0, 0.6), (0.5, 0.5, 0.5)),
         _object("Sheet", "CUBE", (0.1, 0.0, 0.75), (0.7, 0.7, 0.0), rotation=(0.5, 0.3, 0.0), transform="flattened"),
         _object("Post", "CYLINDER", (-1.0, 0.8, 0.5), (0.08, 0.08, 0.5))],
        [_light("Lamp", "POINT", (2.5, -1.5, 3.5), (0.0, 0.0, 0.0), 3000.0, radius=0.002, soft_falloff=True)],
        fuzz.hand_camera((-1.5, -3.5, 2.5), (0.0, 0.0, 0.4)), floor_half_size=5.0)


def test_point_like_light_refines_the_maps():
    """A 2 mm point light: SSM's patches each update about one texel, so its soft shadow map is a hard shadow
    map, and at the paper's ~256 texels its edges came out in steps four times a hard map's (fuzz 28164: a
    sheet cutting a ball, a band of the ball lit along the cut, 0.42 against HARD's 0.12). The maps are refined
    up to the Shadow Map Size while the penumbrae span under 4 texels (ssm_maps.refined_size). 128² against
    Cycles 256 spp: SSM 0.0273 unrefined (256 texels), 0.0112 refined."""
    scene = _point_light_cutting_a_ball()
    refined, _ = fuzz.shadow_score(scene, "SSM", (128, 128), SPP)
    plain, _ = fuzz.shadow_score(scene, "SSM", (128, 128), SPP, overrides=dict(ssm_refine=False))
    print(f"SSM refined {refined['mae_shadow']:.4f}, not refined {plain['mae_shadow']:.4f}")
    assert refined["n_shadow"] > 1000
    assert refined["mae_shadow"] <= 0.5 * plain["mae_shadow"]


@pytest.mark.xfail(strict=True, reason="SSM 0.0112 against HARD 0.0059: where the sheet cuts the ball, a band of "
                   "the ball a few pixels wide comes out half lit (V 0.1-0.7) where HARD and Cycles have it dark")
def test_point_like_light_as_sharp_as_a_hard_shadow_map():
    """With refined maps (above), SSM under a 2 mm light should be as sharp as a hard shadow map. It was
    (0.0164 against HARD's 0.0170) until the depth bias's slope term fell to a tenth of a texel per unit of tan θ
    (common/light_view.glsl SLOPE_BIAS), which brought HARD down to 0.0059 and SSM only to 0.0112."""
    scene = _point_light_cutting_a_ball()
    ssm, _ = fuzz.shadow_score(scene, "SSM", (128, 128), SPP)
    hard, _ = fuzz.shadow_score(scene, "HARD", (128, 128), SPP)
    print(f"SSM {ssm['mae_shadow']:.4f}, HARD {hard['mae_shadow']:.4f} over {ssm['n_shadow']} px")
    assert ssm["n_shadow"] > 1000
    assert ssm["mae_shadow"] <= 1.25 * hard["mae_shadow"]
