"""Registry of shadow techniques: identifier → instance, in the order the UI lists them."""
from ..core.options import CATALOGUE, known_options
from .hard import Hard
from .pcf import Pcf
from .pcss import Pcss
from .averaged import AveragedMaps
from .backprojection import Backprojection
from .ssm import SoftShadowMaps
from .spsm import SubPixelShadowMaps
from .pvsm import Pvsm

TECHNIQUES = CATALOGUE       # the core's catalogue is this registry itself
TECHNIQUES.update((t.identifier, t) for t in (Hard(), Pcf(), Pcss(), AveragedMaps(), SoftShadowMaps(),
                                               Backprojection(), SubPixelShadowMaps(), Pvsm()))


def all_options() -> dict:
    """Every technique option by name."""
    return known_options()


def get(identifier: str):
    try:
        return TECHNIQUES[identifier]
    except KeyError:
        raise ValueError(f"Unknown technique '{identifier}'; choose one of {', '.join(TECHNIQUES)}") from None
