"""Long sweeps, left out of the default run (`pytest -m slow` runs them)."""
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.measure import metrics, reference, scenes  # noqa: E402
from penumbra.engine.render import pipeline
from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402


@pytest.mark.slow
@pytest.mark.parametrize("name", ["plane", "suzanne", "balls"])
def test_reference_converges_to_cycles_with_light_samples(name):
    """REFERENCE at 16, 64, 256 and 1024 light samples against Cycles at 1024 spp: the error falls with the
    samples (10 % slack for the shadow map's own discretisation) and ends within the Cycles noise floor plus
    the 0.005 map allowance used in tests/test_against_cycles.py."""
    sc = scenes.build(name, resolution=(128, 128))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=1024)
    floor = reference.noise_floor(sc, 1024)
    errors = []
    for n in (16, 64, 256, 1024):
        r = pipeline.render(snap, RenderSettings(technique="REFERENCE").with_(averaged_light_samples=n))
        errors.append(metrics.compare(r.passes["Visibility"][..., 0], ref.visibility, ref.mask)["mae_shadow"])
    print(name, errors, "floor", floor["mae_shadow"])
    for a, b in zip(errors, errors[1:]):
        assert b <= a * 1.1
    assert errors[-1] <= floor["mae_shadow"] + 0.005
