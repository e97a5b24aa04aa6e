"""Stage interfaces that every driver compiles. NVIDIA's GLSL compiler (driver 580.159, on an H200) crashed the
process, a segmentation fault inside glLinkProgram, on the conservative map's program, which passed a flat mat3
from its geometry to its fragment stage; with the matrix split into three vec3 it linked (each variant linked in
its own process there: the matrix alone made the difference). Mesa compiles both, so only this check keeps the
form out: SPSM and PVSM, which build that map, would crash Blender itself on such a machine."""
import re

import pytest

from penumbra.engine.gpu.programs import GLSL_ROOT

SOURCES = sorted(p for p in GLSL_ROOT.rglob("*") if p.is_file())
MATRIX_VARYING = re.compile(r"^\s*(?:layout\s*\([^)]*\)\s*)?(?:(?:flat|smooth|noperspective|centroid|sample)\s+)*"
                            r"(?:in|out)\s+d?mat[234](?:x[234])?\b")


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(GLSL_ROOT)))
def test_no_matrix_passes_between_stages(path):
    hits = [f"{i}: {line.strip()}" for i, line in enumerate(path.read_text().splitlines(), 1)
            if MATRIX_VARYING.search(line.split("//")[0])]
    assert not hits, (f"glsl/{path.relative_to(GLSL_ROOT)} passes a matrix between shader stages (pass its "
                      "columns as vectors):\n" + "\n".join(hits))


def test_the_check_sees_the_form_that_crashed():
    assert MATRIX_VARYING.search("flat out mat3 g_edges;")
    assert MATRIX_VARYING.search("layout(location = 2) flat in mat4 m;")
    assert not MATRIX_VARYING.search("uniform mat3 u_m;")
    assert not MATRIX_VARYING.search("mat3 t_edges;")
