"""How a stator's contact acts on the disc, declared by its unit type.

A stator type declares a :class:`ContactLaw`: its kind, which fixes the event
protocol every engine follows, and for a penalty contact the kernel giving the
normal force.

* ``rigid``: impacts (restitution and a Coulomb impulse), the end of chattering,
  then sustained contact held by the constraint force, released when it falls to
  zero (:mod:`.stator`).
* ``penalty``: the disc penetrates the stator; the normal force is the law's
  kernel ``normal(dist, vn, a0, a1, ...)`` (N, > 0 pushes the disc inward) of the
  disc's distance from the stator centre ``dist`` (m, > clearance in contact), its
  outward normal speed relative to the stator ``vn`` (m/s) and the unit's
  quantities named by ``args`` (parameters, those from neighbours, derived ones),
  in that order.  Contact onset and release (the gap through zero) are events;
  friction is Coulomb's on the compressive part of the normal force.

Every engine reaches a penalty law through :func:`penalty_law_normal` (law ``i``,
the ``i``-th penalty law of the registry, its ``args`` packed from ``p[o]`` on):
the reference packs them into its parameter array, the co-simulation's stator
rows after their common head.  The function is generated from the registry
(:mod:`.generated_module`): a new law needs no edit here or in the engines.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from .generated_module import law_dispatch_source, load_generated
from .jit import njit
from .registered import registered

CONTACT_KINDS = ("rigid", "penalty")
# The events a stator's contact makes (the third column of :data:`WATCHED`), numbered
# for compiled code: ``EV_IMPACT`` ... ``EV_OFF``.
EVENT_KINDS = ("impact", "release", "slip", "contact_on", "contact_off")
EV_IMPACT, EV_RELEASE, EV_SLIP, EV_ON, EV_OFF = range(5)

# What a co-simulation master watches of a stator, by its contact kind and state: rows
# of (output crossing zero, direction -1 falling / +1 rising, the event it makes, the
# output holding its time derivative or "").  A rigid stator's state is its contact
# mode (:data:`.stator.MODE_FREE` ... ``MODE_STICK``, the mode the master keeps); a
# penalty stator's is whether its gap is open (0, ``gap > 0``) or closed (1).  Both
# masters read this table; the reference watches the same quantities of its own state.
WATCHED: dict[str, tuple[tuple[tuple[str, int, str, str], ...], ...]] = {
    "rigid": (
        (("gap", -1, "impact", "gap_rate"),),  # free
        (("normal_force", -1, "release", ""), ("slip", -1, "slip", "")),  # sliding, slip > 0
        (("normal_force", -1, "release", ""), ("slip", 1, "slip", "")),  # sliding, slip < 0
        (("normal_force", -1, "release", ""), ("hold_margin", -1, "slip", "")),  # sticking
    ),
    "penalty": (
        (("gap", -1, "contact_on", "gap_rate"),),  # open
        (("gap", 1, "contact_off", "gap_rate"),),  # closed
    ),
}


@njit
def penalty_state(gap: float) -> int:
    """A penalty stator's state in :data:`WATCHED`: 0 open (``gap > 0``, m), 1 closed."""
    return 0 if gap > 0.0 else 1


@dataclass(frozen=True)
class ContactLaw:
    """A stator type's contact (see the module's docstring): ``kind`` one of
    :data:`CONTACT_KINDS`; for a penalty contact, ``normal`` its normal-force kernel and
    ``args`` the names of the quantities it takes after ``(dist, vn)``."""

    kind: str
    normal: Callable[..., float] | None = None
    args: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in CONTACT_KINDS:
            raise ValueError(f"contact kind {self.kind!r} is not one of {CONTACT_KINDS}")
        if (self.kind == "penalty") != (self.normal is not None):
            raise ValueError("a penalty contact, and only a penalty contact, has a normal law")


def penalty_laws() -> tuple[ContactLaw, ...]:
    """The penalty laws of the registered unit types, in registry order, each once
    (law ``i`` is the ``i``-th)."""
    laws: list[ContactLaw] = []
    for t in registered():
        if t.contact is not None and t.contact.kind == "penalty" and t.contact not in laws:
            laws.append(t.contact)
    return tuple(laws)


def law_index(law: ContactLaw | None) -> int:
    """The index of a penalty ``law`` among :func:`penalty_laws` (-1: none, or rigid)."""
    laws = penalty_laws()
    return laws.index(law) if law in laws else -1


def max_law_args() -> int:
    """The most quantities a penalty law takes (the slots an engine reserves for them)."""
    return max((len(law.args) for law in penalty_laws()), default=0)


def dispatch_source() -> str:
    """The text of the generated module: ``penalty_law_normal(law, dist, vn, p, o)``."""
    kernels = [(law.normal, len(law.args)) for law in penalty_laws()]
    return law_dispatch_source(__name__, __package__, "penalty_law_normal", "dist, vn", kernels,
                               "0.0")  # fmt: skip


def _load() -> ModuleType:
    return load_generated(dispatch_source(), "contact_laws", __package__, "contact law")


def __getattr__(name: str) -> Any:
    """``penalty_law_normal``: generated and imported on first access (numba resolves
    it when it compiles a caller)."""
    if name != "penalty_law_normal":
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    function = _load().penalty_law_normal
    globals()[name] = function
    return function
