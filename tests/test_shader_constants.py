"""Constants and relations the shaders share with Python are written once: the shared defines reach every
program, no shader repeats their literals, and the GLSL penumbra spread agrees with its Python twin."""
import re
from pathlib import Path

import numpy as np
import pytest

from penumbra.engine.core import shader_constants
from penumbra.engine.core.light_shape import penumbra_spread
from penumbra.engine.gpu.context import GpuWorker
from penumbra.engine.gpu.probes import penumbra_spread_at
from penumbra.engine.gpu.programs import GLSL_ROOT, expand

SOURCES = sorted(p for p in GLSL_ROOT.rglob("*") if p.is_file())


def test_every_program_gets_the_shared_defines():
    source, _ = expand("backprojection/visibility.comp", {"BITS": 8})
    for name, value in shader_constants.DEFINES.items():
        assert re.search(rf"^#define {name} {re.escape(shader_constants.glsl_literal(value))}$", source, re.M), name
    assert "#define BITS 8" in source


# The values of the sentinels and the fixed-point scale, however a shader might spell them.
LITERALS = re.compile(r"\b(3(\.0*)?e\+?38|1(\.0*)?e\+?37|1(\.0*)?e\+?30|16777216(\.0*)?)\b")


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(GLSL_ROOT)))
def test_no_shader_repeats_a_shared_constant(path):
    hits = [f"{i}: {line.strip()}" for i, line in enumerate(path.read_text().splitlines(), 1)
            if LITERALS.search(line.split("//")[0])]
    assert not hits, f"glsl/{path.relative_to(GLSL_ROOT)} spells a shared constant (use its #define):\n" + "\n".join(hits)


@pytest.mark.parametrize("ortho", [False, True])
def test_glsl_penumbra_spread_matches_python(ortho):
    rng = np.random.default_rng(3)
    z = rng.uniform(0.05, 5.0, 500)
    d = z + rng.uniform(-1.0, 5.0, 500)          # receivers in front of and behind the occluders
    d = np.maximum(d, 0.06)
    z[:3] = 0.0                                   # occluders on the light plane: clamped form stays finite
    got = GpuWorker.get().submit(penumbra_spread_at, z, d, ortho).result()
    want = penumbra_spread(np.where(ortho, z, np.maximum(z, 1e-30)), d, ortho)
    finite = z > 0
    with np.errstate(divide="ignore"):
        exact = penumbra_spread(z, d, ortho)
    np.testing.assert_allclose(got[finite, 0], exact[finite], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(got[:, 1], np.maximum(want, 0.0).astype(np.float32), rtol=1e-5, atol=1e-6)
    assert np.all(got[:, 1] >= 0.0)
