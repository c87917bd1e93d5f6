"""How a bearing acts on the journal, declared by its unit type.

A bearing type declares a :class:`BearingLaw`: the kernel giving the force on the
journal, ``force(x, y, vx, vy, a0, a1, ...) -> (fx, fy)`` (N) of the journal's
displacement from the bearing centre (m) and its velocity (m/s), and the unit's
quantities named by ``args`` (parameters, those from neighbours, derived ones), in that
order.  A law whose force ends at a wall (the oil film at the radial clearance) names
the quantity that is the wall's radius (``wall``): beyond it the kernel gives no finite
force, and every engine reports that as the journal touching the wall.

Every engine reaches a bearing through :func:`bearing_law_force` (law ``i``, the
``i``-th bearing law of the registry, its ``args`` packed from ``p[o]`` on): the
reference packs them into its parameter array (``IP_BEARING_LAW``,
``P_BEARING_LAW_0``, ...), the co-simulation's bearing rows after the law's index.  The
function is generated from the registry (:mod:`.generated_module`): a bearing type
without states of its own is its module and a line in the registry.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from .generated_module import law_dispatch_source, load_generated
from .registered import registered


@dataclass(frozen=True)
class BearingLaw:
    """A bearing type's force law (see the module's docstring): ``force`` its kernel,
    ``args`` the names of the quantities it takes after the journal state, ``wall``
    the one of them that is the radius (m) where its force ends ("" for none: the
    journal must start inside it), ``positive`` those of them that must be > 0 for the
    law to hold (the oil film's spin) and ``model`` what a message calls the law."""

    force: Callable[..., tuple[float, float]]
    args: tuple[str, ...]
    wall: str = ""
    model: str = "the bearing's force law"
    positive: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.wall and self.wall not in self.args:
            raise ValueError(f"bearing law: its wall {self.wall!r} is not one of its args")
        for name in self.positive:
            if name not in self.args:
                raise ValueError(f"bearing law: its positive {name!r} is not one of its args")


def bearing_laws() -> tuple[BearingLaw, ...]:
    """The bearing laws of the registered unit types, in registry order, each once
    (law ``i`` is the ``i``-th)."""
    laws: list[BearingLaw] = []
    for t in registered():
        if t.bearing is not None and t.bearing not in laws:
            laws.append(t.bearing)
    return tuple(laws)


def law_index(law: BearingLaw | None) -> int:
    """The index of ``law`` among :func:`bearing_laws` (-1: none)."""
    laws = bearing_laws()
    return laws.index(law) if law in laws else -1


def wall_ratio(law: int, x: float, y: float, args: Any) -> float:
    """The journal's distance from the centre over law ``law``'s wall radius (``args``
    its quantities, in order); 0 for a law without a wall."""
    found = bearing_laws()[law]
    if not found.wall:
        return 0.0
    return math.hypot(x, y) / float(args[found.args.index(found.wall)])


def dispatch_source() -> str:
    """The text of the generated module: ``bearing_law_force(law, x, y, vx, vy, p, o)``."""
    kernels = [(law.force, len(law.args)) for law in bearing_laws()]
    return law_dispatch_source(__name__, __package__, "bearing_law_force", "x, y, vx, vy",
                               kernels, "0.0, 0.0")  # fmt: skip


def _load() -> ModuleType:
    return load_generated(dispatch_source(), "bearing_laws", __package__, "bearing law")


def __getattr__(name: str) -> Any:
    """``bearing_law_force``: generated and imported on first access (numba resolves it
    when it compiles a caller)."""
    if name != "bearing_law_force":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    function = _load().bearing_law_force
    globals()[name] = function
    return function
