"""An area light that crosses a large blocking plane (issue 10, fuzz seed 8423: an 11 × 11.8 m rectangle light
tilted through a room and a 47 m floor, the camera inside the room). Each REFERENCE sample's view is fitted
from its own point of the light, and the floor's box straddles that point's plane. lightview._tangent_window
took the unbounded side of a straddling box from the corners behind the plane, but the plane cuts the box
elsewhere: for samples high on the light every corner behind lay on one side while the cut lay on the other,
the caster window came out bounded there, the view's window (receivers ∩ casters) left most receivers off
the map, and a receiver off the map counts as lit (seed 8423: REFERENCE mean V 0.30 against Cycles' 0.21,
mae_shadow 0.096, bound 0.038; 0.015 after).
Unbounded on the right side, a box that straddles the plane where its points do not (a small light tilted over
a large floor, fuzz 8217: every lit point in front of the light, the floor's far corners behind it) gave a
clamped, coarse single view: the pipeline refits such a view to its lit points, and REFERENCE's samples fit
theirs to those points' grid cells (lightview.cell_corners). Cycles references are cached."""

import numpy as np
import pytest

from penumbra.engine.core import lightview
from penumbra.engine.core.snapshot import AREA, RECTANGLE, Light
from penumbra.engine.techniques.averaged import light_samples

RES = (64, 64)

# fuzz 8217's scene, rounded: a 0.17 × 0.31 mm rectangle light 2.3 m above a 25 m floor, tilted 45°, five
# objects whose shadows have 1 px lines at 128²
SMALL_TILTED_LIGHT = {
    "seed": 0,
    "objects": [
        dict(name="Obj0", primitive="CYLINDER", transform="mirrored", location=[1.01, 0.07, 1.08],
             rotation=[-0.29, 0.3, -1.59], scale=[-1.17, 1.08, -1.01], smooth=False),
        dict(name="Obj1", primitive="MONKEY", transform="nonuniform", location=[0.93, 0.1, 0.33],
             rotation=[0.89, -3.09, 0.39], scale=[1.02, 0.3, 0.44], smooth=False),
        dict(name="Obj2", primitive="CYLINDER", transform="nonuniform", location=[-0.74, 0.7, 0.37],
             rotation=[1.64, -1.71, 0.39], scale=[0.27, 0.32, 0.25], smooth=False),
        dict(name="Obj3", primitive="CUBE", transform="plain", location=[-0.51, 0.95, 0.04],
             rotation=[-0.31, -2.47, -1.25], scale=[0.5, 0.5, 0.5], smooth=False),
        dict(name="Obj4", primitive="CONE", transform="mirrored", location=[-0.59, 1.16, 0.2],
             rotation=[-3.02, 0.34, -0.58], scale=[1.18, 0.35, -0.43], smooth=True)],
    "floor": dict(half_size=12.76, rotation=[0.0, 0.0, 0.0], z=-0.2),
    "lights": [dict(name="Light0", type="AREA", shape="RECTANGLE", size=0.00017, size_y=0.00031,
                    location=[-1.9, 0.9, 2.08], target=[-0.68, 0.1, 0.82], scale=[1, 1, 1], scale_kind="one",
                    distance=2.58, energy=636.0)],
    "camera": dict(ortho=False, location=[-5.81, 2.28, 1.98], target=[0.63, -0.5, 1.07], lens=50.39,
                   ortho_scale=5.87, inside=None),
}

# A box room around the camera, a 40 m floor, an 11 × 12 m rectangle light inside the room, tilted, whose upper
# half leaves the room through its ceiling and whose lower half lies under the floor.
ROOM_FLOOR_LIGHT = {
    "seed": 0,
    "objects": [dict(name="Box", primitive="CUBE", transform="plain", location=[-0.8, -1.0, 0.5],
                     rotation=[0.3, 0.2, 0.5], scale=[0.4, 0.4, 0.4], smooth=False),
                dict(name="Room", primitive="CUBE", transform="room", location=[0.0, 0.0, 1.2],
                     rotation=[0.0, 0.0, 0.0], scale=[2.8, 3.5, 2.6], smooth=False)],
    "floor": dict(half_size=20.0, rotation=[0.0, 0.0, 0.0], z=-0.06),
    "lights": [dict(name="Light0", type="AREA", shape="RECTANGLE", size=11.0, size_y=12.0,
                    location=[-0.4, 1.3, -0.08], target=[-0.5, 0.1, 0.45], scale=[1, 1, 1], scale_kind="one",
                    distance=1.0, energy=80.0)],
    "camera": dict(ortho=False, location=[0.0, 1.35, 1.8], target=[-1.1, -1.6, 2.2], lens=50.0, ortho_scale=3.0,
                   inside="Room"),
}


def _tilted_area_light(direction, position) -> Light:
    z = -np.asarray(direction, float)
    z /= np.linalg.norm(z)
    x = np.array([1.0, 0.0, 0.0]) - z * z[0]
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, position
    light = Light(name="L", kind=AREA, matrix=m, color=np.ones(3), power=1.0)
    light.shape, light.size_x, light.size_y = RECTANGLE, 11.0, 12.0
    return light


def test_every_sample_view_holds_the_receivers_when_the_casters_straddle_its_plane():
    """The room-and-floor geometry without a renderer: from every sample point of the light, the receivers'
    box (in front of it) projects inside the sample view's window, though the casters' box (floor and room)
    straddles the sample's plane. Before: samples 2–4 m from the centre along the light's Y had windows that
    cut the receivers off."""
    light = _tilted_area_light([0.0, -1.2, 0.5], [0.0, 1.3, 0.0])
    receivers = (np.array([-2.5, -3.2, 1.1]), np.array([-0.2, -1.0, 3.3]))
    casters = (np.array([-24.0, -24.0, -1.4]), np.array([24.0, 24.0, 3.8]))
    corners = lightview.box_corners(*receivers)
    checked = 0
    for offset in light_samples(light, 64, seed=0):
        origin = np.array([offset[0], offset[1], 0.0])
        view = lightview.fit(light, receivers, casters, 256, origin_local=origin)
        local = lightview.to_local(view.view, corners)
        if np.any(local[:, 2] >= 0.0):
            continue                    # part of the receivers behind this sample: no single view holds them
        t = local[:, :2] / -local[:, 2:3]
        x0, x1, y0, y1 = view.window
        assert np.all((t[:, 0] >= x0) & (t[:, 0] <= x1) & (t[:, 1] >= y0) & (t[:, 1] <= y1)), (offset, view.window)
        checked += 1
    assert checked > 32


def test_a_straddling_box_is_unbounded_where_the_plane_cuts_it():
    """A box whose corners behind the eye's plane all lie at y > 0 but which the plane cuts at y < 0: its
    points just in front of the plane there have tangents going to −∞, so the window is open below, and the
    cut has no point at y > 0, so above it ends at the front corners' largest tangent (−12/25). Before: the
    other way round (bounded below at −17/23, open above)."""
    corners = np.array([[0.0, -17.0, -23.0], [0.0, -12.0, -25.0], [0.0, 2.0, 19.0], [0.0, 7.0, 17.0]])
    win, _ = lightview._tangent_window(corners, 1e-5)
    assert win[2] == -np.inf and win[3] == pytest.approx(-12.0 / 25.0)


def test_reference_within_bound_with_a_light_through_the_room_and_floor():
    """REFERENCE (64 samples) within the fuzz's bound. Measured at 64², 256 spp: 0.082 before (bound 0.038),
    0.029 after (0.013 at 256 samples: the rest is the 64 hard maps' steps)."""
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, bound = fuzz.shadow_score(ROOM_FLOOR_LIGHT, "REFERENCE", RES, overrides={"averaged_light_samples": 64})
    print(f"mae_shadow {m['mae_shadow']:.4f} over {m['n_shadow']} px, bound {bound:.4f}")
    assert m["n_shadow"] > 2000
    assert m["mae_shadow"] <= bound


def test_lit_points_bound_the_window_where_their_box_straddles_the_plane():
    """Points of a floor all in front of a light tilted over it, whose box reaches behind the light's
    plane: fitted to the box the view is clamped (its window unbounded on that side); fitted to the points,
    or to their grid cells' corners, it is not, and it holds every point."""
    light = _tilted_area_light([1.0, 1.0, -1.4], [0.0, 0.0, 2.0])
    rng = np.random.default_rng(1)
    floor = np.column_stack([rng.uniform(-2.0, 6.0, 4000), rng.uniform(-2.0, 6.0, 4000), np.zeros(4000)])
    local = lightview.to_local(np.linalg.inv(light.matrix), floor)
    points = floor[-local[:, 2] > 1.0]                   # the lit part: well in front of the light's plane
    box = (points.min(axis=0), points.max(axis=0))
    casters = (box[0] - [0.0, 0.0, 0.0], box[1] + [0.0, 0.0, 1.0])      # the floor and what stands on it
    assert lightview.fit(light, box, casters, 256).clamped
    for fitted_to in (points, lightview.cell_corners(points)):
        view = lightview.fit(light, box, casters, 256, receiver_points=fitted_to)
        assert not view.clamped
        assert not lightview.outside_view(view, points).any()


def test_small_tilted_light_over_a_large_floor_within_bound():
    """REFERENCE within the fuzz's bound. Measured at 128², 256 spp: 0.036 before (bound 0.032), 0.012 after
    (HARD, whose bound is far looser: 0.036 and 0.010)."""
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, bound = fuzz.shadow_score(SMALL_TILTED_LIGHT, "REFERENCE", (128, 128))
    print(f"mae_shadow {m['mae_shadow']:.4f} over {m['n_shadow']} px, bound {bound:.4f}")
    assert m["n_shadow"] > 1000
    assert m["mae_shadow"] <= bound
