"""Views per light: a light whose lit pixels do not fit one shadow map is seen through its single view plus
cube faces, and no pixel is ever treated as lit because it fell outside every map."""
import dataclasses

import numpy as np
import pytest

from penumbra.engine.core import lightview
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.measure import stress
from penumbra.engine.render import pipeline
from penumbra.engine.render.pipeline import TECHNIQUES


def _light(position=(0.0, 0.0, 2.0), size=0.6):
    return stress.area_light(position, size=size)


def _scattered_receivers(rng):
    """A light whose single view must clamp (4000 receivers all around it, above and below its plane), the
    receivers, their box and that view."""
    light = _light()
    pts = rng.uniform(-3, 3, (4000, 3))
    pts[:, 2] = rng.uniform(0.0, 4.0, 4000)
    receivers = (pts.min(axis=0), pts.max(axis=0))
    return light, pts, receivers, lightview.fit(light, receivers, receivers, 256)


def test_faces_partition_the_points_and_each_face_holds_what_it_owns():
    light, pts, receivers, view = _scattered_receivers(np.random.default_rng(3))
    faces = lightview.split_faces(view, pts)
    assert faces is not None and faces[0][0] is None   # the single view keeps what it holds
    owned = np.sum([mask for _, mask in faces], axis=0)
    assert (owned == 1).all(), "every point belongs to exactly one view"
    assert not lightview.outside_view(view, pts[faces[0][1]]).any()
    for rotation, mask in faces[1:]:
        assert np.allclose(rotation @ rotation.T, np.eye(3)) and np.isclose(np.linalg.det(rotation), 1.0)
        sub = pts[mask]
        face = lightview.fit(light, (sub.min(axis=0), sub.max(axis=0)), receivers, 256, frame=view.view,
                             face=rotation)
        assert not lightview.outside_view(face, sub).any(), "a face must hold every point it owns"


def test_the_single_view_keeps_a_point_only_if_it_holds_where_its_shadow_ray_starts():
    """A point the clamped view holds whose lifted start (the terminator lift) lies past its window goes to a
    cube face, chosen by the point itself; a face fitted to its points and their lifted starts holds both."""
    rng = np.random.default_rng(3)
    light, pts, receivers, view = _scattered_receivers(rng)
    lifted = pts + rng.normal(0.0, 0.05, pts.shape)
    plain = lightview.split_faces(view, pts)
    faces = lightview.split_faces(view, pts, lifted)
    kept = faces[0][1]
    assert not lightview.outside_view(view, lifted[kept]).any()
    moved = plain[0][1] & ~kept
    assert moved.any(), "some lifted starts must leave the single view, or this test shows nothing"
    owned = np.sum([mask for _, mask in faces], axis=0)
    assert (owned == 1).all()
    for rotation, mask in faces[1:]:
        both = np.concatenate([pts[mask], lifted[mask]])
        face = lightview.fit(light, (both.min(axis=0), both.max(axis=0)), receivers, 256, frame=view.view,
                             face=rotation, receiver_points=both)
        assert not lightview.outside_view(face, both).any()


def test_the_single_view_keeps_only_what_a_view_from_every_point_of_the_light_holds():
    """With the light's extent as the margin, a point the clamped view holds within margin/depth of its window's
    edge goes to a cube face: a view from a point of the light that far off the centre, looking the same way,
    holds every point the single view keeps (REFERENCE's sample maps look from there)."""
    light, pts, receivers, view = _scattered_receivers(np.random.default_rng(3))
    margin = 0.3 * np.sqrt(2.0)             # the 0.6 m square's half diagonal
    plain = lightview.split_faces(view, pts)
    faces = lightview.split_faces(view, pts, margin=margin)
    kept = faces[0][1]
    assert (plain[0][1] & ~kept).any(), "some points must leave the single view, or this test shows nothing"
    assert (np.sum([mask for _, mask in faces], axis=0) == 1).all()
    to_world = np.linalg.inv(view.view)
    for corner in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        shifted = view.view.copy()
        offset = to_world[:3, :3] @ np.array([corner[0] * 0.3, corner[1] * 0.3, 0.0])
        shifted[:3, 3] -= view.view[:3, :3] @ offset          # the same view, its eye moved by `offset`
        moved = dataclasses.replace(view, view=shifted)
        assert not lightview.outside_view(moved, pts[kept]).any()


def test_a_view_that_holds_every_point_is_not_split():
    light = _light()
    pts = np.array([[0.2, 0.1, 0.0], [-0.5, 0.3, 0.0], [0.0, 0.0, 1.0]])
    view = lightview.fit(light, (pts.min(axis=0), pts.max(axis=0)), None, 256)
    assert lightview.split_faces(view, pts) is None


def test_a_face_fits_the_points_it_owns_not_their_box():
    """A face's points lie within 45° of its axis, but the far corners of their box can lie far outside that
    pyramid (or behind the eye), which widened the face's window up to the tangent limit and coarsened its
    texels. Fitted to the points themselves, every face's window stays within the pyramid (plus the margin)."""
    light, pts, receivers, view = _scattered_receivers(np.random.default_rng(5))
    faces = lightview.split_faces(view, pts)
    wide = 0
    for rotation, mask in faces[1:]:
        sub = pts[mask]
        box = (sub.min(axis=0), sub.max(axis=0))
        tight = lightview.fit(light, box, receivers, 256, frame=view.view, face=rotation, receiver_points=sub)
        loose = lightview.fit(light, box, receivers, 256, frame=view.view, face=rotation)
        assert not lightview.outside_view(tight, sub).any()
        assert np.abs(tight.window).max() <= 1.0 * (1.0 + 2 * 0.02) + 1e-9, tight.window
        wide += np.abs(loose.window).max() > 1.1
    assert wide, "the box's corners must reach outside some face's pyramid, or this test shows nothing"


def test_a_view_with_nothing_to_shadow_is_not_clamped():
    """Receivers that no caster's window reaches need no map. With receivers and casters both around the
    light's plane, on opposite sides of it, both windows are unbounded across and the empty part they share
    kept an infinite bound: the view counted as clamped, split into faces and warned that pixels fell outside
    its views (fuzz seed 7407). Casters that do reach over the receivers still clamp it."""
    light = _light(size=0.0)                                            # looking down -Z from z = 2
    receivers = (np.array([2.0, -0.5, 0.0]), np.array([3.0, 0.5, 3.0]))
    apart = (np.array([-3.0, -0.5, 1.5]), np.array([-2.0, 0.5, 2.5]))
    over = (np.array([-3.0, -0.5, 1.5]), np.array([3.0, 0.5, 2.5]))
    assert not lightview.fit(light, receivers, apart, 256).clamped
    assert lightview.fit(light, receivers, over, 256).clamped


def test_a_caster_behind_the_eye_over_receivers_behind_it_clamps_the_view():
    """A point light's view looks at its receivers' middle: a large floor reaching far to one side turns it
    away from a caster on the other, behind the eye's plane with the floor under it. Nothing in front is
    shadowable, but the floor behind is: the view must count as clamped so that those pixels get cube faces
    (fuzz 9145: mae_shadow 0.997 → 0.003, the shadow was simply missing)."""
    from dataclasses import replace
    from penumbra.engine.core.snapshot import POINT
    light = replace(_light(size=0.0), kind=POINT, radius=0.0)            # a point at z = 2
    floor = (np.array([-3.0, -1.0, 0.0]), np.array([19.0, 1.0, 0.1]))   # its middle at x = 8: the view faces +X
    behind = (np.array([-2.0, -0.5, 0.0]), np.array([-1.0, 0.5, 1.0]))
    assert lightview.fit(light, floor, behind, 256).clamped
    assert not lightview.fit(light, (np.array([3.0, -1.0, 0.0]), np.array([19.0, 1.0, 0.1])), behind, 256).clamped


def room_with_light():
    """An area light in a closed room with a block beside it under the ceiling: the walls next to the light
    are lit at grazing angles and the block shadows a wall far off the light's axis."""
    parts = [("Room", stress.box((-2, -2, 0), (2, 2, 3), inward=True), True, True),
             ("Block", stress.box((0.6, -0.3, 2.35), (1.2, 0.3, 2.65)), True, True)]
    cam = stress.camera(eye=(-1.6, -1.6, 1.2), target=(1.0, 0.5, 1.8), fov=80.0)
    return stress.assemble(parts, [_light((0.0, 0.0, 2.6), size=0.4)], cam, "room_with_light")


@pytest.fixture(scope="module")
def room():
    snap = room_with_light()
    return snap, stress.oracle(snap, n=12)


@pytest.mark.parametrize("technique", list(TECHNIQUES))
def test_no_pixel_is_treated_as_lit_outside_the_maps(room, technique):
    snap, truth = room
    result = pipeline.render(snap, RenderSettings(technique=technique))
    assert not [w for w in result.warnings if "outside" in w], result.warnings
    assert result.stats.get("lights_split") == 1 and result.stats.get("views", 0) >= 2
    v = result.passes["Visibility"][..., 0]
    ref = truth["V"]
    umbra = ref < 0.02
    assert umbra.sum() > 50, "the scene must have an umbra off the light's axis"
    # Wherever the truth is umbra, a pixel left outside every map would read 1 (lit).
    assert float(np.mean(v[umbra])) < 0.1, f"{technique}: mean V {np.mean(v[umbra]):.3f} in the umbra"


def test_averaged_maps_match_the_oracle_in_the_room(room):
    snap, truth = room
    v = pipeline.render(snap, RenderSettings(technique="REFERENCE")).passes["Visibility"][..., 0]
    ref = truth["V"]
    valid = np.isfinite(ref)
    shadow = valid & ((ref < 0.99) | (v < 0.99))
    mae = float(np.mean(np.abs(v[shadow] - ref[shadow])))
    # 0.03: 64 light samples against the oracle's 144 (both discretise the light), measured 0.01-0.02
    assert mae < 0.03, mae


def test_sun_rim_views_take_the_receivers_whose_horizon_hides_the_centre():
    """core.lightview.sun_rim_faces: receivers with the sun's centre below their horizon go to a view from the
    rim point of the disk nearest their normal, which lies above their horizon while the disk reaches it; the
    others keep the centre's view."""
    from penumbra.engine.core.snapshot import SUN, Light
    rng = np.random.default_rng(5)
    angle = 2.4
    light = Light("Sun", SUN, np.eye(4), np.ones(3), 1.0, angle=angle)   # towards the sun: world +z
    normals = rng.normal(size=(3000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    pts = rng.uniform(-2, 2, (3000, 3))
    view = lightview.fit(light, (pts.min(axis=0), pts.max(axis=0)), None, 256)
    faces = lightview.sun_rim_faces(light, view, normals, normals)
    assert faces[0][0] is None and (faces[0][1] == (normals[:, 2] > 0.0)).all()
    assert (np.sum([mask for _, mask in faces], axis=0) == 1).all(), "every point belongs to exactly one view"
    assert len(faces) == 1 + lightview.SUN_RIM_VIEWS
    polar = np.arccos(normals[:, 2])
    for rotation, mask in faces[1:]:
        to_rim = rotation[2]                    # the view's +z, towards its rim point, in the sun's frame
        assert np.isclose(np.arccos(to_rim[2]), angle / 2)
        # The rim point nearest a normal makes cos(polar − angle/2) with it; rounding the azimuth to 45° costs
        # at most 1 − cos 22.5° < 0.08 of that.
        seen = mask & (np.cos(polar - angle / 2) > 0.08)
        assert seen.sum() > 100 and (normals[seen] @ to_rim > 0.0).all()
    facing = normals * [1, 1, 0] + [0, 0, 0.5]      # every normal above the horizon: nothing to add
    assert lightview.sun_rim_faces(light, view, facing, facing) is None


def test_the_rim_views_gate_uses_the_suns_frame_axis():
    """The pipeline builds rim views only where render/lit_bounds.comp counts lit pixels with the direction
    towards the sun (-Light.direction) below their horizon; sun_rim_faces tests against its view's +z. The two
    must be the same axis for any sun orientation, or the gate would skip pixels sun_rim_faces would take."""
    from penumbra.engine.core.snapshot import SUN, Light
    rng = np.random.default_rng(11)
    for _ in range(8):
        q, _r = np.linalg.qr(rng.normal(size=(3, 3)))
        m = np.eye(4)
        m[:3, :3] = q * np.sign(np.linalg.det(q))
        light = Light("Sun", SUN, m, np.ones(3), 1.0, angle=1.0)
        pts = rng.uniform(-2, 2, (50, 3))
        view = lightview.fit(light, (pts.min(axis=0), pts.max(axis=0)), None, 64)
        np.testing.assert_allclose(np.asarray(view.view)[2, :3], -light.direction, atol=1e-9)


def test_a_part_views_map_is_as_fine_as_its_pixels_need():
    """needed_map_size: PART_MAP_TEXELS_PER_PIXEL texels across the pixel footprint at every point a part
    view holds, from the camera's tangent per pixel and the point's depths; clamped to [PART_MAP_LEAST,
    size]."""
    from penumbra.engine.core.snapshot import Camera
    light = _light(position=(0.0, 0.0, 4.0))
    pts = np.array([[0.3, 0.2, 0.0], [-0.4, 0.1, 0.0], [0.0, -0.3, 0.0]])
    view = lightview.fit(light, (pts.min(axis=0), pts.max(axis=0)), None, 1024)
    eye = np.array([0.0, -6.0, 3.0])
    proj = stress.perspective(np.radians(40.0), 1.0, 0.1, 100.0)
    camera = Camera("C", np.linalg.inv(stress.look_at(eye, (0.0, 0.0, 0.0))), proj, 128, 128)
    per_pixel = 2.0 / (proj[1, 1] * 128)
    x0, x1, y0, y1 = view.window
    cam_depth = -(np.c_[pts, np.ones(3)] @ camera.view[2])
    light_depth = -(np.c_[pts, np.ones(3)] @ view.view[2])
    expected = np.max(lightview.PART_MAP_TEXELS_PER_PIXEL * max(x1 - x0, y1 - y0) * light_depth
                      / (cam_depth * per_pixel))
    got = lightview.needed_map_size(view, pts, camera, 1024)
    assert got == max(lightview.PART_MAP_LEAST, int(np.ceil(expected))), (got, expected)
    assert got < 1024                                   # a few pixels' part at 128²: far from the full size
    # a finer image needs finer texels, up to the size asked for
    fine = Camera("C", camera.view, proj, 4096, 4096)
    assert got < lightview.needed_map_size(view, pts, fine, 1024) <= 1024
    assert lightview.needed_map_size(view, pts, Camera("C", camera.view, proj, 1 << 16, 1 << 16), 1024) == 1024
    # and a coarse one no less than PART_MAP_LEAST
    assert lightview.needed_map_size(view, pts, Camera("C", camera.view, proj, 4, 4), 1024) == \
        lightview.PART_MAP_LEAST
