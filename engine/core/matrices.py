"""Matrix packing shared by the math layer and the GPU layer (no GL here)."""
from __future__ import annotations

import numpy as np


def mat_uniform(m) -> tuple:
    """A numpy matrix as the column-major float tuple a GLSL mat3/mat4 uniform takes."""
    return tuple(np.asarray(m, dtype=np.float32).T.ravel())
