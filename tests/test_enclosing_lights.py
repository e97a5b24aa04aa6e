"""Sphere lights larger than the space they light (issue 10, fuzz seeds 3011, 533, 27009, 28000): the built-in
`room` (a closed 6 × 5 × 3 m box) with its light grown until the walls, floor and ceiling cut through it,
against Cycles. The Unshadowed pass agrees with Cycles (within 0.3 %); what is at stake is the Visibility.
Cycles' shadow rays end on the emitter: the disk through the centre facing the receiver (soft falloff) or the
sphere's surface. REFERENCE's light samples fill the light's ball (averaged.projected_disk_ball), each a
shadow map whose rays end at the sample point, so once geometry lies inside the ball the two meet different
surfaces. A true sphere: receivers outside it read maps without the casters inside it (averaged._sphere_clip),
receivers inside it sample its surface, each such map looking towards the centre. A soft falloff
(SIDE_BEYOND_DISK): each receiver takes only the samples beyond its facing disk, weighed by their density
along the ray past the disk, and its test looks past the surfaces between the sample and the disk (two
peeled layers behind each map). Before, with every ball sample and one layer: soft_disk_r2 0.046, r4 0.122
(bounds 0.038 and 0.041; ball points behind the walls but nearer than the disk stayed lit), after 0.024 and
0.028; the r = 0.15 light of the same room is the control, whose ball holds nothing and keeps every sample.
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
    "control_r0.15": (0.15, True, 2.4),
    "soft_disk_r2": (2.0, True, 1.5),
    # the disk facing each receiver is wider than the room
    "soft_disk_r4": (4.0, True, 1.5),
    # receivers outside the sphere read maps without the casters inside it (averaged._sphere_clip): their
    # error fell from 0.101 to 0.007; those inside it (13 % of the pixels) sample its surface, from 0.157 to
    # 0.071, still too bright while each surface sample's map kept the light's axis (V 0.79 vs 0.75: samples
    # below a receiver could not see it and were left out). With each map looking from its point towards the
    # centre: mae_shadow 0.040 -> 0.011 (bound 0.037)
    "true_sphere_r2": (2.0, False, 1.5),
}


# the soft-falloff cases take ~15 s each on the CI machine (twice the samples, three layers each): the wider
# one runs with the slow sweeps
@pytest.mark.heavy
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c == "soft_disk_r4" else c
                                  for c in CASES])
def test_reference_matches_cycles_with_the_light_filling_the_room(case):
    radius, soft, height = CASES[case]
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
