"""Paper studies, one module per paper: `python -m penumbra bench --study NAME --out DIR [-- options]`.
Each module has a `main(argv)` with its own options."""
from __future__ import annotations

import importlib

STUDIES = {
    "backprojection": "Schwarz & Stamminger 2007, bitmask soft shadows: Tables 2/3 columns",
    "ssm": "Atty et al. 2006, soft shadow maps: map size, precision, timing (§4.2, §5.2.3)",
    "spsm": "Lecocq et al. 2014, sub-pixel shadow maps vs HARD: pixel match, time, look-up shares, quantiser",
    "pvsm": "Shen et al. 2011, predicted virtual soft shadow maps: closed form, anti-aliasing, stages, ρ, tiles",
    "msaa": "Schwarz & Stamminger 2008 §7, one visibility sample per pixel: MSAA overhead and edge error per technique",
    "quality-scalability": "Schwarz & Stamminger 2008, quality scalability: budgets, blending, microrects, YSM",
}


def run(name: str, argv: list[str]) -> int:
    if name not in STUDIES:
        raise ValueError(f"Unknown study '{name}'; choose one of {', '.join(STUDIES)}")
    return importlib.import_module(f"{__name__}.{name.replace('-', '_')}").main(argv)
