"""Concave corners under PCF and PCSS (issue 10): a room's walls where they meet, a floor where it meets a wall.

A filter that reaches texels beside the receiver's own compares each with the receiver's plane extended under it.
At a concave edge the other surface lies in front of that extended plane, though it faces the light and the
receiver both, so it came out as a blocker: PCF drew every room's corners as dark lines (fuzz 30032, 30088,
30118; Cycles has them lit). Each texel now also knows its triangle's plane (the facet map), and a triangle
with the receiver and the light on one side of its plane is no blocker (light_view.glsl facet_clears_receiver):
in PCF's filter with the light's centre (the view's origin), in PCSS's blocker search with the whole light
(core/light_shape.py light_reach_box). 64², Cycles 256 spp."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import fuzz  # noqa: E402


def test_pcf_leaves_a_rooms_corners_lit_in_a_random_scene():
    """Fuzz 30032: a point light inside a room, the camera inside it facing a corner where two walls meet the
    ceiling, the light's other casters out of view. Cycles has every pixel lit; PCF darkened the corner lines to
    V 0.57-0.80 (mae_shadow 0.158 over 106 pixels, bound 0.079). With the facet map: no pixel below 0.99."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(30032), "PCF")
    print("30032 PCF", m["mae_shadow"], "bound", limit, "pixels", m["n_shadow"])
    assert m["n_shadow"] == 0 or m["mae_shadow"] <= limit


def test_pcss_leaves_a_rooms_corners_lit_under_an_area_light():
    """Fuzz 30118: a 0.4 x 1.1 m rectangle light inside a room, the camera inside it. Cycles has the walls' corners
    lit; PCSS's blocker search found the far wall of each corner in front of the near wall's extended plane and its
    filter darkened the corner (mae_shadow 0.189 over 101 pixels, bound 0.170). With the facet test in the search:
    0.123 over 26 pixels (bound 0.227); the filter, which runs where the search still finds a blocker, does not
    test facets (pcss/visibility.comp says why). A wall that has the receiver in front but the light partly behind it still blocks (the
    whole light's box must lie in front)."""
    m, limit = fuzz.shadow_score(fuzz.scene_params(30118), "PCSS")
    print("30118 PCSS", m["mae_shadow"], "bound", limit, "pixels", m["n_shadow"])
    assert m["n_shadow"] == 0 or m["mae_shadow"] <= limit


def _room_with_a_ball() -> dict:
    room = fuzz.hand_object("Room", "CUBE", (0.0, 0.0, 1.2), (2.0, 1.6, 1.5), transform="room")
    ball = fuzz.hand_object("Ball", "UV_SPHERE", (0.8, -0.6, 0.4), (0.4, 0.4, 0.4), smooth=True)
    lamp = fuzz.hand_light("Lamp", "POINT", (1.2, 0.9, 2.2), (1.4, 0.9, 0.0), 800.0, radius=0.0, soft_falloff=True)
    camera = fuzz.hand_camera((-1.0, 0.8, 1.5), (2.0, -1.6, 0.8), 24.0, inside="Room")
    return fuzz.hand_scene([room, ball], [lamp], camera, floor_half_size=8.0, floor_rotation=(0.2, -0.1, 0.0))


def _grow(mask: np.ndarray, steps: int) -> np.ndarray:
    for _ in range(steps):
        grown = mask.copy()
        grown[1:] |= mask[:-1]
        grown[:-1] |= mask[1:]
        grown[:, 1:] |= mask[:, :-1]
        grown[:, :-1] |= mask[:, 1:]
        mask = grown
    return mask


def test_pcf_darkens_no_corner_of_a_room_away_from_real_shadows():
    """A ball on a tilted floor that cuts through a room, a point light inside. Away from Cycles' shadows (three
    pixels and more from any pixel it has below 0.99, beyond PCF's legitimate blur) every pixel must stay lit.
    Before the facet map PCF darkened 4 of those 3747 pixels, on the corners between the walls and the floor."""
    from penumbra.engine.blender.extract import extract
    from penumbra.engine.core.settings import RenderSettings
    from penumbra.engine.render import pipeline
    scene = fuzz.build(_room_with_a_ball(), (64, 64))
    cyc = fuzz.cycles_side(scene, 64, 64, 256)
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    v = pipeline.render(snap, RenderSettings(antialiasing=False, technique="PCF")).passes["Visibility"][..., 0]
    far = cyc.ref.mask & ~_grow(cyc.ref.visibility < 0.99, 3)
    assert far.sum() > 3000
    dark = far & (v < 0.99)
    assert not dark.any(), f"{int(dark.sum())} lit pixels darkened, down to {float(v[dark].min()):.3f}"


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize("kind", ["AREA", "POINT", "SUN"])
def test_light_reach_box_holds_the_whole_light_from_any_view(kind):
    """The box facet_clears_receiver tests against must hold every point of the light (every direction towards a
    sun, as tangents) in any view's frame: the light's own, a cube face, a rim view, a random one."""
    from types import SimpleNamespace

    from penumbra.engine.core.light_shape import light_reach_box
    from penumbra.engine.core.snapshot import Light
    rng = np.random.default_rng(7)
    for _ in range(50):
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = _rotation(rng), rng.normal(size=3)
        light = Light("L", kind, matrix, np.ones(3), 1.0, size_x=float(rng.uniform(0.01, 3.0)),
                      size_y=float(rng.uniform(0.01, 3.0)), radius=float(rng.uniform(0.0, 2.0)),
                      angle=float(rng.uniform(0.0, 2.5)))
        view = np.eye(4)
        view[:3, :3] = _rotation(rng)
        view[:3, 3] = 0.0 if kind == "SUN" else -view[:3, :3] @ (light.position + rng.normal(size=3) * 0.5)
        box = np.asarray(light_reach_box(light, SimpleNamespace(view=view)))
        if kind == "SUN":
            # directions towards the sun: within angle/2 of its axis (-direction)
            k = rng.normal(size=(400, 3))
            k -= np.outer(k @ -light.direction, -light.direction)
            k /= np.linalg.norm(k, axis=1, keepdims=True)
            a = rng.uniform(0.0, light.angle / 2.0, size=(400, 1))
            d = (np.cos(a) * -light.direction + np.sin(a) * k) @ view[:3, :3].T
            ahead = d[:, 2] > 1e-3
            t = np.abs(d[ahead, :2] / d[ahead, 2:3])
            assert np.all(t <= box[:2] * (1 + 1e-9) + 1e-9)
            continue
        if kind == "AREA":
            u = rng.uniform(-1.0, 1.0, size=(400, 2)) * (light.size_x / 2.0, light.size_y / 2.0)
            points = light.position + u @ matrix[:3, :2].T
        else:
            s = rng.normal(size=(400, 3))
            points = light.position + light.radius * s / np.linalg.norm(s, axis=1, keepdims=True)
        local = points @ view[:3, :3].T + view[:3, 3]
        assert np.all(np.abs(local) <= box * (1 + 1e-9) + 1e-9)
