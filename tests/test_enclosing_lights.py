"""Sphere lights larger than the space they light (issue 10, fuzz seeds 3011 and 533): the built-in `room`
(a closed 6 × 5 × 3 m box) with its light grown until the walls, floor and ceiling cut through it, against
Cycles. What is measured here: the Unshadowed pass agrees with Cycles (within 0.3 %), the Visibility does
not. REFERENCE's light samples fill the light's ball (averaged.projected_disk_ball), each a shadow map whose
rays end at the sample point; Cycles' shadow rays end on the emitter, the disk through the centre facing the
receiver (soft falloff) or the sphere's surface. Once walls pass through the ball, the walls between a
receiver and a ball point are not those between it and the emitter: with a soft falloff a ball point behind
a wall but nearer than the disk stays lit (REFERENCE too bright), and a true sphere's points deep inside
its volume are cut off by the floor or a wall that the ray to its near surface clears (too dark). For a
true sphere REFERENCE now follows Cycles' rays (averaged._sphere_clip): receivers outside it read maps without
the casters inside it, receivers inside it sample its surface. Shared shadow maps from fixed points cannot
follow a disk that turns with every receiver, so the soft-falloff cases stay strict xfails with the measured
numbers; the true sphere passes since each of its surface samples looks towards its centre; the r = 0.15
light of the same room is the control. Tried and left out: each cube face sampling the disk through the centre across its own axis (the
rays end on the emitter's plane as Cycles' do, but the disk is foreshortened up to 55° off the face axis)
takes soft_disk_r4 from 0.181 to 0.116 and soft_disk_r2 from 0.047 to 0.050, still far over their bounds.
Also tried: a ball sample's ray to a receiver is the ray of Cycles' disk point on it, so the two differ only
in where the ray ends; ball samples short of the disk left out and, for those past it, texels nearer the
sample than the disk not counted take r4 from 0.122 to 0.208 and r2 from 0.046 to 0.054 (a wall between
the sample and the disk, nearest in its map, hides the casters behind it; a map keeps one depth per texel),
and 0.252 / 0.128 without that cut.
Fuzz seed 6020 is this class too (its 4.66 m soft point light alone: REFERENCE 0.18; its 1.4 rad sun with a
non-uniform scale alone: 0.000, as Cycles takes only the direction of a sun's Z axis). Cycles references
are cached."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.measure import fuzz, metrics, scenes  # noqa: E402
from penumbra.engine.measure.compare import unshadowed_error  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402

RES = (64, 64)
SPP = 256


def _room(radius: float, soft: bool, height: float):
    sc = scenes.build("room", resolution=RES)
    light = sc.objects[scenes.LIGHT_NAME]
    light.data.shadow_soft_size = radius
    light.data.use_soft_falloff = soft
    light.location.z = height
    bpy.context.view_layer.update()
    return sc


CASES = {
    # the built-in room's own light, 0.6 m under the ceiling: far smaller than the room
    "control_r0.15": (0.15, True, 2.4, None),
    "soft_disk_r2": (2.0, True, 1.5, "REFERENCE mae_shadow 0.046 (bound 0.038): ball points behind the walls "
                                     "but nearer than Cycles' disk facing each receiver stay lit (V 0.89 vs 0.86)"),
    "soft_disk_r4": (4.0, True, 1.5, "REFERENCE mae_shadow 0.122 (0.181 before the samples weighed the "
                                     "facing disk's cosine and rim): the disk facing each receiver is wider "
                                     "than the room (V 0.63 vs 0.59 before)"),
    # receivers outside the sphere read maps without the casters inside it (averaged._sphere_clip): their
    # error fell from 0.101 to 0.007; those inside it (13 % of the pixels) sample its surface, from 0.157 to
    # 0.071, still too bright while each surface sample's map kept the light's axis (V 0.79 vs 0.75: samples
    # below a receiver could not see it and were left out). With each map looking from its point towards the
    # centre: mae_shadow 0.040 -> 0.011 (bound 0.037)
    "true_sphere_r2": (2.0, False, 1.5, None),
}


# the failing cases take ~20 s each on the CI machine, so they run with the slow sweeps
@pytest.mark.parametrize("case", [pytest.param(c, marks=[pytest.mark.xfail(strict=True, reason=v[3]),
                                                         pytest.mark.slow])
                                  if v[3] else c for c, v in CASES.items()])
def test_reference_matches_cycles_with_the_light_filling_the_room(case):
    radius, soft, height, _ = CASES[case]
    sc = _room(radius, soft, height)
    cyc = fuzz.cycles_side(sc, RES[0], RES[1], SPP)             # the reference and its noise floor
    ref = cyc.ref
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    r = pipeline.render(snap, RenderSettings(antialiasing=False).with_(technique="REFERENCE", debug_passes=True))
    # the unoccluded light is right in every case: only the Visibility is at stake
    assert unshadowed_error(r.passes["Irradiance"] / np.pi, ref.unshadowed, ref.mask) < 0.01
    m = metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)
    bound = fuzz.bound("REFERENCE", cyc.floor["mae_shadow"], m["n_shadow"])     # the fuzz's own bound
    print(f"{case}: mae_shadow {m['mae_shadow']:.4f} bound {bound:.4f}")
    assert m["mae_shadow"] <= bound, f"{case}: mae_shadow {m['mae_shadow']:.4f} > {bound:.4f}"
