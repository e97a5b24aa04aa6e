"""Casters that cannot shadow what a light reaches stay out of its view (issue 10: tilted floors, lights in
rooms). A flat caster shadows only what lies beyond its plane; a convex caster that holds the light and every
lit pixel shadows nothing. Left in, they stretch the light's map over the whole scene, and its texels then
miss small or thin casters (fuzz seed 73: a flattened cylinder over a tilted floor, inside a huge sphere)."""
import numpy as np

from penumbra.engine.core import lightview
from penumbra.engine.measure import stress
from penumbra.engine.techniques.averaged import projected_disk_ball


def _rotation_x(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _tilted_floor_scene(pebble_below=False):
    """A 25° tilted floor, a small block resting on it, an area light above; optionally a block poking
    through to the floor's far side."""
    turn = _rotation_x(np.radians(25))
    floor = stress.quad((0, 0, 0), 4.0) @ turn.T
    block = stress.box((-0.2, -0.2, 0.3), (0.2, 0.2, 0.7)) @ turn.T
    parts = [("Floor", floor, True, True), ("Block", block, True, True)]
    if pebble_below:
        parts.append(("Pebble", stress.box((1.0, 1.0, -0.6), (1.3, 1.3, -0.2)) @ turn.T, True, True))
    light = stress.area_light((0.0, -1.0, 4.0), size=0.5)
    return stress.assemble(parts, [light], stress.camera(), "tilted"), light


def _caster_bounds(snap, light, points):
    sides = lightview.receiver_sides([light], snap.flat_objects(), snap.convex_objects(), points)
    casters = np.array([o.caster for o in snap.objects])
    receivers = (points.min(axis=0), points.max(axis=0))
    return lightview.shadowing_caster_bounds(light, snap.object_bounds(), casters, receivers, sides)


def test_a_tilted_floor_is_flat_and_shadows_nothing_on_its_light_side():
    snap, light = _tilted_floor_scene()
    flat = snap.flat_objects()
    assert 0 in flat and 1 not in flat
    normal, _ = flat[0]
    assert np.isclose(abs(normal @ _rotation_x(np.radians(25))[:, 2]), 1.0)
    points = snap.positions.reshape(-1, 3).astype(np.float64)          # every vertex lit
    lo, hi = _caster_bounds(snap, light, points)
    block = snap.object_bounds()[1]
    assert np.allclose(lo, block[0]) and np.allclose(hi, block[1]), "only the block can shadow"


def test_a_tilted_floor_stays_a_caster_when_something_lit_lies_beyond_it():
    snap, light = _tilted_floor_scene(pebble_below=True)
    points = snap.positions.reshape(-1, 3).astype(np.float64)
    lo, hi = _caster_bounds(snap, light, points)
    floor = snap.object_bounds()[0]
    assert np.all(lo <= floor[0] + 1e-6) and np.all(hi >= floor[1] - 1e-6)


def test_a_room_holding_the_light_and_every_lit_pixel_shadows_nothing_but_what_is_inside():
    room = stress.box((-3, -3, 0), (3, 3, 3), inward=True)
    block = stress.box((-0.3, -0.3, 0.0), (0.3, 0.3, 0.6))
    light = stress.area_light((0.5, 0.0, 2.0), size=0.4)
    snap = stress.assemble([("Room", room, True, True), ("Block", block, True, True)], [light],
                           stress.camera(), "room")
    assert set(snap.convex_objects()) == {0, 1}
    inside = np.random.default_rng(1).uniform((-2.9, -2.9, 0.0), (2.9, 2.9, 2.9), (500, 3))
    lo, hi = _caster_bounds(snap, light, inside)
    assert np.allclose(lo, snap.object_bounds()[1][0]) and np.allclose(hi, snap.object_bounds()[1][1])
    # A lit point outside the room (seen through nothing, but lit by the light's emission test): the walls
    # would shadow it, so they stay.
    outside = np.vstack([inside, [[5.0, 0.0, 1.0]]])
    lo, hi = _caster_bounds(snap, light, outside)
    assert np.allclose(lo, snap.object_bounds()[0][0]) and np.allclose(hi, snap.object_bounds()[0][1])


def test_sphere_light_ball_samples_project_to_a_uniform_disk_in_every_direction():
    """REFERENCE samples a sphere light's ball when its receivers surround it: every receiver must see the
    samples spread uniformly over the disk facing it (Cycles' soft falloff), whatever its direction."""
    p = projected_disk_ball(40000, seed=2)
    assert np.all(np.linalg.norm(p, axis=1) <= 1.0 + 1e-9)
    for d in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0), np.array([1.0, 0.0, 0.0])):
        rho2 = np.sum((p - np.outer(p @ d, d)) ** 2, axis=1)
        counts = np.histogram(rho2, bins=8, range=(0.0, 1.0))[0]      # uniform disk: ρ² uniform
        assert np.abs(counts / counts.mean() - 1.0).max() < 0.05, counts


def test_a_low_area_light_over_the_ground_is_on_one_side_of_it():
    """The light's reach across a plane is its rectangle's support along the normal, not its half diagonal:
    a 2.5 m square 1.74 m up, facing the horizon, reaches 1.25 m down and stays above the ground."""
    elev = np.radians(5.0)
    pos = (-20.0 * np.cos(elev), 0.0, 20.0 * np.sin(elev))
    light = stress.area_light(pos, target=(0.0, 0.0, 0.0), size=2.5)
    ground = np.array([0.0, 0.0, 1.0])
    assert lightview._light_side(light, ground, 0.0) == 1.0
    assert lightview._light_side(light, ground, 1.0) == 0.0        # a plane at 1 m: the square spans it
    reach = float(lightview._light_reach(light, ground))
    assert reach < 1.26 < 0.5 * np.hypot(2.5, 2.5)


def test_a_closed_convex_shell_around_the_camera_hides_every_light_outside_it():
    """lightview.enclosing_shell, which lets SSM leave a light unlit on every visible receiver (fuzz 8005, 8010,
    8015, 8107: the camera inside a huge ball under a sun): the camera's near plane strictly inside a closed
    convex caster, the light wholly outside it. Not for a light inside the shell, a camera outside it, a
    shell with a face missing (an open box lets light in), or a shell that is no caster."""
    from penumbra.engine.core.snapshot import SUN, Light
    room = stress.box((-3, -3, 0), (3, 3, 3))
    sun = Light("Sun", SUN, stress.look_at((4.0, 2.0, 9.0), (0.0, 0.0, 0.0)), np.ones(3), 3.0, angle=3.0)
    lamp = stress.area_light((0.5, 0.0, 2.0), size=0.4)
    far_lamp = stress.area_light((0.5, 0.0, 5.0), size=0.4)          # above the roof
    inside, outside = stress.camera(eye=(1.5, -1.5, 1.5), target=(0, 0, 0.5), fov=70.0), stress.camera()
    snap = stress.assemble([("Room", room, True, True)], [sun], inside, "room")
    assert lightview.enclosing_shell(snap, sun, [0]) == 0
    assert lightview.enclosing_shell(snap, far_lamp, [0]) == 0
    assert lightview.enclosing_shell(snap, lamp, [0]) is None
    assert lightview.enclosing_shell(snap, sun, []) is None
    assert lightview.enclosing_shell(stress.assemble([("Room", room, True, True)], [sun], outside, "out"),
                                     sun, [0]) is None
    # the room without its roof (the two triangles whose corners all lie at z = 3)
    open_room = room[~np.all(np.isclose(room[:, :, 2], 3.0), axis=1)]
    assert len(open_room) == 10
    snap = stress.assemble([("Room", open_room, True, True)], [sun], inside, "open")
    assert not snap.is_closed(0)
    assert lightview.enclosing_shell(snap, sun, [0]) is None


def _box_planes():
    box = stress.box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0))
    snap = stress.assemble([("Box", box, True, True)], [], stress.camera(), "box")
    return snap.convex_objects()[0]


def test_a_convex_caster_cannot_shadow_its_own_surface_facing_the_lights_centre():
    """A point on a convex object's face whose plane has the light's centre in front, seen from outside:
    every technique's tangent-plane rule keeps the object (all behind that plane) from shadowing it, even
    where part of a wide light lies behind the plane. Seen from inside (the wall of a room around the camera)
    the object lies in front of the receiver's plane and may shadow it; so may it a point on the face turned
    away from the centre."""
    normals, offsets = _box_planes()
    from dataclasses import replace
    from penumbra.engine.core.snapshot import POINT
    # a sphere light reaching below the top face's plane z = 1, its centre above it
    light = replace(stress.area_light((0.2, 0.0, 3.0)), kind=POINT, radius=2.5)
    top = np.array([[0.1, 0.2, 1.0], [-0.45, 0.4, 1.0]])
    up, down = np.tile([0.0, 0.0, 1.0], (2, 1)), np.tile([0.0, 0.0, -1.0], (2, 1))
    assert lightview.faces_clear_light(light, normals, offsets, top, None, up, 1e-5)
    assert not lightview.faces_clear_light(light, normals, offsets, top, None, down, 1e-5)
    assert not lightview.faces_clear_light(light, normals, offsets, top, None, None, 1e-5)
    side, out = np.array([[0.5, 0.0, 0.5]]), np.array([[1.0, 0.0, 0.0]])
    assert not lightview.faces_clear_light(light, normals, offsets, side, None, out, 1e-5)   # centre behind it
    beside = replace(light, matrix=stress.area_light((1.5, 0.0, 3.0)).matrix)      # now in front of it
    assert lightview.faces_clear_light(beside, normals, offsets, side, None, out, 1e-5)
    low = stress.area_light((3.0, 0.0, 0.5), size=0.2)           # beside the box: its -x face looks away
    assert not lightview.faces_clear_light(low, normals, offsets, np.array([[-0.5, 0.0, 0.5]]), None, -out, 1e-5)


def test_a_convex_caster_shadows_a_point_off_it_unless_a_face_plane_parts_them_from_the_whole_light():
    normals, offsets = _box_planes()
    floor_point = np.array([[3.0, 0.0, 0.0]])
    above = stress.area_light((3.0, 0.0, 4.0), size=0.5)        # wholly beyond the +x face's plane, as the point
    assert lightview.faces_clear_light(above, normals, offsets, floor_point, None, None, 1e-5)
    wide = stress.area_light((3.0, 0.0, 4.0), size=6.0)         # reaches past that plane: the box may shadow
    assert not lightview.faces_clear_light(wide, normals, offsets, floor_point, None, None, 1e-5)
    across = stress.area_light((-3.0, 0.0, 1.0), size=0.5)      # the box between light and point
    assert not lightview.faces_clear_light(across, normals, offsets, floor_point, None, None, 1e-5)
    # where the shadow ray leaves from counts too: a lifted point behind every plane facing the light
    lifted = np.array([[0.4, 0.0, 0.9]])
    assert not lightview.faces_clear_light(above, normals, offsets, floor_point, lifted, None, 1e-5)


def _dented_box(lo, hi, dent):
    """A closed box whose roof is pushed in to a point `dent` below its centre: closed, not convex."""
    box = stress.box(lo, hi)
    walls = box[~np.all(np.isclose(box[:, :, 2], hi[2]), axis=1)]
    (x0, y0, _), (x1, y1, z1) = lo, hi
    apex = ((x0 + x1) / 2.0, (y0 + y1) / 2.0, z1 - dent)
    rim = [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    roof = [(rim[k], rim[(k + 1) % 4], apex) for k in range(4)]          # counter-clockwise seen from above
    return np.concatenate([walls, np.array(roof, float)])


def test_a_closed_shell_that_is_not_convex_hides_every_light_outside_it():
    """lightview.enclosing_shell beyond convex casters (fuzz: a huge torus or dented solid around the camera):
    the side of a ball around the near plane and one around the light, by a ray's crossings of the closed
    surface. Not for a light on the camera's side, or one whose emitter reaches through the surface; a lamp
    inside with the camera outside is walled off too."""
    from penumbra.engine.core import solids
    from penumbra.engine.core.snapshot import SUN, Light
    room = _dented_box((-3, -3, 0), (3, 3, 3), dent=1.5)
    sun = Light("Sun", SUN, stress.look_at((4.0, 2.0, 9.0), (0.0, 0.0, 0.0)), np.ones(3), 3.0, angle=3.0)
    inside, outside = stress.camera(eye=(1.5, -1.5, 1.0), target=(0, 0, 0.5), fov=70.0), stress.camera()
    snap = stress.assemble([("Room", room, True, True)], [sun], inside, "dented")
    assert snap.is_closed(0) and 0 not in snap.convex_objects()
    assert lightview.enclosing_shell(snap, sun, [0]) == 0
    assert lightview.enclosing_shell(snap, stress.area_light((0.0, 0.0, 2.8), size=0.4), [0]) == 0    # in the dent
    assert lightview.enclosing_shell(snap, stress.area_light((2.0, 0.0, 1.0), size=0.4), [0]) is None  # in the room
    assert lightview.enclosing_shell(snap, stress.area_light((0.0, 0.0, 1.6), size=0.4), [0]) is None  # through the roof
    assert lightview.enclosing_shell(stress.assemble([("Room", room, True, True)], [sun], outside, "out"),
                                     sun, [0]) is None
    # the other way round: a lamp inside the closed room, the camera outside it
    assert lightview.enclosing_shell(stress.assemble([("Room", room, True, True)], [sun], outside, "out"),
                                     stress.area_light((2.0, 0.0, 1.0), size=0.4), [0]) == 0
    # the crossing count itself: a ray from inside leaves once, one from the dent's hollow crosses the roof twice
    assert solids.ball_inside(room, (1.0, -1.0, 1.0), 0.5) is True
    assert solids.ball_inside(room, (0.0, 0.2, 2.9), 0.05) is False
    assert solids.ball_inside(room, (0.0, 0.0, 1.5), 0.1) is None                      # on the dent's tip
