"""Layout of an assembled system's arrays, derived from the unit declarations.

``ip`` (integers) says which units a system has and where their states are;
``p`` (reals) holds every parameter in SI units.  For the rotor family (every
unit type of the registry that is not a hybrid, whole-model type: rotors,
stators, bearings, controllers) both layouts are computed here from the
declarations (:mod:`rubcosim.components.registry`), in registry order:

* ``p``: after the system's own slots (:data:`SYSTEM_SLOTS`), one slot per role
  and quantity the role's types pack (:func:`packed_names`: real parameters
  that set no initial state, then those taken from neighbours, then derived
  ones), shared by the role's types that have it: ``P_STATOR_CLEARANCE``.
* ``ip``: the family and the state count, then per role the code of its type
  (``IP_STATOR`` holds ``STATOR_NONE`` = 0 or ``STATOR_RIGID``, ... numbered 1,
  2, ... in registry order), the index of each choice parameter's value
  (``IP_CONTROLLER_FEEDBACK`` holds ``CONTROLLER_FEEDBACK_POSITION``, ...) and
  the state offset of each declared state (``IP_ROTOR_JOURNAL_X``; -1 if absent).
* a role whose types declare a law the engines call (a stator's penalty contact law,
  a bearing's force law): the law's index (``IP_STATOR_LAW``, ``IP_BEARING_LAW``; -1
  for none) and the quantities it takes, side by side from ``P_STATOR_LAW_0``.

Every slot is a module-level integer (numba compiles them as constants into
the kernels of :mod:`.system`, where this module is re-exported); adding a
parameter to a declaration adds its slot here, with no edit.  Compiled kernels
that depend on these numbers are cached in a directory keyed on the sources compiled
code can reach, the declarations among them (:mod:`rubcosim.compile_key`), so a changed
declaration never meets a stale kernel.  Event kinds name what an event did
(:data:`KIND_NAMES`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcosim.components import bearing_law, contact_law
from rubcosim.components.declaration import UnitType

# Event kinds and the number of event slots are shared with the hybrid unit types.
from rubcosim.components.hybrid_dispatch import (  # noqa: F401
    KIND_BREAK,
    KIND_CONTACT_OFF,
    KIND_CONTACT_ON,
    KIND_IMPACT,
    KIND_NAMES,
    KIND_RELEASE,
    KIND_SLIP,
    N_EVENTS,
)

# Rotor modes MODE_FREE, MODE_SLIDE_POS, MODE_SLIDE_NEG, MODE_STICK: components.stator.
# The impact oscillator's modes: stuck on the barrier +D / -D (free: MODE_FREE = 0)
from rubcosim.components.oscillator_unit import STUCK_LOWER as MODE_STUCK_LOWER
from rubcosim.components.oscillator_unit import STUCK_UPPER as MODE_STUCK_UPPER
from rubcosim.components.registry import REGISTRY

FAMILY_ROTOR = 0
FAMILY_HYBRID = 1  # hybrid unit type i (rubcosim.components.hybrid_dispatch) is 1 + i

N_DELAYED = 4  # the controller feeds back the disc state (x, y, vx, vy)

# The system's own integer slots: its family and its number of states.
SYSTEM_INT_SLOTS = ("family", "nstate")
# The system's own real slots, set from its scales:
# vchat: normal speed below which a rebound counts as settled (chattering ends), m/s;
# omega_b: Baumgarte rate of the sustained-contact constraint, rad/s.
SYSTEM_SLOTS = ("vchat", "omega_b")


def constant_name(text: str) -> str:
    """``text`` as a module constant's name (a choice's value may hold a ``-``)."""
    return re.sub(r"\W", "_", text).upper()


def packed_names(t: UnitType) -> tuple[str, ...]:
    """The quantities the reference packs into ``p`` for a unit of type ``t``: its real
    (and integer, boolean) parameters except those giving a state's initial value, the
    parameters it takes from its neighbours, then its derived quantities."""
    initial = {s.initial for s in t.states}
    own = [p.name for p in t.params if p.kind != "choice" and p.name not in initial]
    return tuple(dict.fromkeys((*own, *(n.param for n in t.needs), *(d.name for d in t.derived))))


def declared_law(t: UnitType) -> tuple[Any, int] | None:
    """The law of a unit of type ``t`` that the engines call through a generated dispatch,
    with its index there: a penalty contact law (:mod:`rubcosim.components.contact_law`)
    or a bearing law (:mod:`rubcosim.components.bearing_law`); None for neither."""
    if t.contact is not None and t.contact.kind == "penalty":
        return t.contact, contact_law.law_index(t.contact)
    if t.bearing is not None:
        return t.bearing, bearing_law.law_index(t.bearing)
    return None


def choice_params(t: UnitType) -> dict[str, tuple[str, ...]]:
    """Choice parameter -> its choices, for a unit of type ``t`` (packed into ``ip``)."""
    return {p.name: p.choices for p in t.params if p.kind == "choice"}


@dataclass
class Layout:
    """The slots of the rotor family's arrays (see the module's docstring)."""

    roles: tuple[str, ...]
    p: dict[tuple[str, str], int] = field(default_factory=dict)  # (role, quantity) -> slot
    ip_type: dict[str, int] = field(default_factory=dict)  # role -> slot of its type code
    codes: dict[tuple[str, str], int] = field(default_factory=dict)  # (role, type) -> code
    ip_choice: dict[tuple[str, str], int] = field(default_factory=dict)  # (role, param)
    ip_state: dict[tuple[str, str], int] = field(default_factory=dict)  # (role, state)
    ip_law: dict[str, int] = field(default_factory=dict)  # role -> slot of its law's index
    p_law: dict[str, int] = field(default_factory=dict)  # role -> first slot of its law's args
    constants: dict[str, int] = field(default_factory=dict)  # name -> value, exported
    n_p: int = 0
    n_ip: int = 0

    def _constant(self, name: str, value: int) -> None:
        name = constant_name(name)
        if name in self.constants:
            raise ValueError(f"the reference's array layout names {name} twice")
        self.constants[name] = value

    def new_arrays(self, n_p: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Zero ``p`` (at least ``n_p`` long) and ``ip`` with every state offset -1."""
        ip = np.zeros(self.n_ip, dtype=np.int64)
        for slot in (*self.ip_state.values(), *self.ip_law.values()):
            ip[slot] = -1
        return np.zeros(max(self.n_p, n_p)), ip

    def pack(self, role: str, t: UnitType, values: Mapping[str, Any], p, ip) -> None:
        """Write a unit of ``role`` and type ``t`` with ``values`` (its parameters, those
        from its neighbours and its derived quantities) into ``p`` and ``ip``."""
        ip[self.ip_type[role]] = self.codes[(role, t.type_name)]
        for name in packed_names(t):
            p[self.p[(role, name)]] = values[name]
        for name, choices in choice_params(t).items():
            ip[self.ip_choice[(role, name)]] = choices.index(values[name])
        law = declared_law(t)
        if law is not None:
            ip[self.ip_law[role]] = law[1]
            for j, name in enumerate(law[0].args):
                p[self.p_law[role] + j] = values[name]


def rotor_family_layout(types: Iterable[UnitType]) -> Layout:
    """The layout of the rotor family made of ``types`` (registry order)."""
    types = [t for t in types if t.hybrid is None]
    layout = Layout(tuple(dict.fromkeys(t.role for t in types)))
    for i, name in enumerate(SYSTEM_INT_SLOTS):
        layout._constant(f"IP_{name}", i)
    for i, name in enumerate(SYSTEM_SLOTS):
        layout._constant(f"P_{name}", i)
    n_ip, n_p = len(SYSTEM_INT_SLOTS), len(SYSTEM_SLOTS)

    def add(table: dict, key: tuple[str, ...] | str, name: str, count: int) -> int:
        if key in table:
            return count
        table[key] = count
        layout._constant(name, count)
        return count + 1

    for role in layout.roles:
        kinds = [t for t in types if t.role == role]
        n_ip = add(layout.ip_type, role, f"IP_{role}", n_ip)
        layout._constant(f"{role}_NONE", 0)
        for code, t in enumerate(kinds, start=1):
            layout.codes[(role, t.type_name)] = code
            layout._constant(f"{role}_{t.type_name}", code)
        for t in kinds:
            for name in packed_names(t):
                n_p = add(layout.p, (role, name), f"P_{role}_{name}", n_p)
            for name, choices in choice_params(t).items():
                n_ip = add(layout.ip_choice, (role, name), f"IP_{role}_{name}", n_ip)
                for index, value in enumerate(choices):
                    key = f"{role}_{name}_{value}"
                    if layout.constants.get(constant_name(key)) != index:
                        layout._constant(key, index)  # (a second type with the choice: skip)
            for s in t.states:
                n_ip = add(layout.ip_state, (role, s.name), f"IP_{role}_{s.name}", n_ip)
        # a declared law's index, and the quantities it takes side by side (the engines
        # call every law of a role alike: contact_law.penalty_law_normal,
        # bearing_law.bearing_law_force)
        laws = [law[0] for t in kinds if (law := declared_law(t)) is not None]
        if laws:
            n_ip = add(layout.ip_law, role, f"IP_{role}_LAW", n_ip)
            layout.p_law[role] = n_p
            for j in range(max(len(law.args) for law in laws)):
                layout._constant(f"P_{role}_LAW_{j}", n_p)
                n_p += 1
    layout.n_p, layout.n_ip = n_p, n_ip
    return layout


LAYOUT = rotor_family_layout(REGISTRY)
# The kernels of .system read the disc at y[0:4]: the rotor must be the first role and
# declare the disc's states first.
if LAYOUT.roles[0] != "rotor" or any(
    tuple(s.name for s in t.states[:4]) != ("x", "y", "vx", "vy")
    for t in REGISTRY
    if t.role == "rotor"
):
    raise ImportError("the registry must list the rotor types first, disc states first")
N_P, N_IP = LAYOUT.n_p, LAYOUT.n_ip
globals().update(LAYOUT.constants)
# The most states a system can have: every state slot of the rotor family, or the
# largest hybrid unit type (the length of the engines' scratch arrays on the stack).
MAX_STATES = max(len(LAYOUT.ip_state), *(len(t.states) for t in REGISTRY if t.hybrid))

__all__ = [
    *LAYOUT.constants,
    "FAMILY_HYBRID",
    "FAMILY_ROTOR",
    "KIND_BREAK",
    "KIND_CONTACT_OFF",
    "KIND_CONTACT_ON",
    "KIND_IMPACT",
    "KIND_NAMES",
    "KIND_RELEASE",
    "KIND_SLIP",
    "LAYOUT",
    "MAX_STATES",
    "MODE_STUCK_LOWER",
    "MODE_STUCK_UPPER",
    "N_DELAYED",
    "N_EVENTS",
    "N_IP",
    "N_P",
]
