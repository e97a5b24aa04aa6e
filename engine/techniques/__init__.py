"""Registry of shadow techniques: identifier → instance, in the order the UI lists them."""
from .hard import Hard
from .pcf import Pcf
from .pcss import Pcss
from .averaged import AveragedMaps
from .backprojection import Backprojection
from .ssm import SoftShadowMaps

TECHNIQUES = {t.identifier: t for t in (Hard(), Pcf(), Pcss(), AveragedMaps(), SoftShadowMaps(), Backprojection())}


def all_options() -> dict:
    """Every technique option by name."""
    return {opt.name: opt for t in TECHNIQUES.values() for opt in t.options}


def get(identifier: str):
    try:
        return TECHNIQUES[identifier]
    except KeyError:
        raise ValueError(f"Unknown technique '{identifier}'; choose one of {', '.join(TECHNIQUES)}") from None
