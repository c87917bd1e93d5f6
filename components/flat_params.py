"""Which row form a unit type has in the compiled co-simulation master, and its
parameter row.

:func:`flat_type` says how the master steps and reads a unit (its flat kind, its ODE
kind of :mod:`.unit_odes`, the names of its parameter row, the inputs its ODE takes);
:func:`flat_params` packs a unit's parameter row.  The rotors, the rigid stator and the
controller are listed in :data:`FLAT_TYPES`; a penalty stator's row and a bearing's
follow from its declared law (:mod:`.contact_law`, :mod:`.bearing_law`), a hybrid
type's from its kernels (:mod:`.flat_hybrid`).  The unit classes (:class:`.flat_units.RowOutputs`)
and the compiled master (:mod:`rubcosim.orchestrator.flat_master`) read them alike.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from . import bearing_law
from .contact_law import law_index
from .flat_controller import controller_params
from .flat_hybrid import hybrid_flat_type, hybrid_params
from .flat_rows import (
    K_BEARING,
    K_CASING,
    K_CONTROLLER,
    K_JEFFCOTT,
    K_PENALTY,
    K_RIGID,
    K_TWO_MASS,
    MAX_PARAMS,
)
from .registered import declaration
from .unit_odes import CASING, JEFFCOTT, JEFFCOTT_P, LAW, LAW_AT, PENALTY_P, TWO_MASS, TWO_MASS_P

RIGID_P = (
    "x_offset",
    "y_offset",
    "restitution",
    "friction",
    "disc_radius",
    "speed",
    "clearance",
    "disc_mass",
    "constraint_rate",
)

# (role, type name) -> (flat kind, ODE kind of unit_odes or -1, parameter names, ODE inputs)
FLAT_TYPES: dict[tuple[str, str], tuple[int, int, tuple[str, ...], tuple[str, ...]]] = {
    ("rotor", "jeffcott"): (K_JEFFCOTT, JEFFCOTT, JEFFCOTT_P, ("fx", "fy")),
    ("rotor", "two_mass"): (
        K_TWO_MASS,
        TWO_MASS,
        TWO_MASS_P,
        ("fx", "fy", "journal_fx", "journal_fy"),
    ),
    ("stator", "rigid"): (K_RIGID, -1, RIGID_P, ()),
    ("controller", "delayed_feedback"): (K_CONTROLLER, -1, (), ()),
}


def _penalty_type(role: str, type_name: str) -> Any:
    """The declaration of a stator type with a penalty law (:mod:`.contact_law`), or None."""
    t = declaration(role, type_name)
    return t if t is not None and t.contact is not None and t.contact.kind == "penalty" else None


def flat_type(role: str, type_name: str) -> tuple[int, int, tuple, tuple] | None:
    """The :data:`FLAT_TYPES` entry of a unit type, the penalty stators' (from their
    declaration: on a casing with states, massless without), the bearings' (any declared
    law) and the hybrid types' (:func:`.flat_hybrid.hybrid_flat_type`) included; None
    when it has no row form."""
    entry = FLAT_TYPES.get((role, type_name))
    if entry is not None:
        return entry
    t = declaration(role, type_name)
    if t is not None and t.bearing is not None:
        return K_BEARING, -1, t.bearing.args, ()
    t = _penalty_type(role, type_name)
    if t is not None:
        if t.states:
            # its ODE reads the disc state (unit_odes.CASING)
            return K_CASING, CASING, PENALTY_P, ("x", "y", "vx", "vy")
        return K_PENALTY, -1, PENALTY_P, ()
    return hybrid_flat_type(role, type_name)


def penalty_params(t: Any, params: Mapping[str, Any]) -> np.ndarray:
    """The parameter row of a penalty stator of declaration ``t``: :data:`PENALTY_P` (a
    quantity the type does not have is 0), its law's index at ``LAW``, then the
    quantities its law takes (its parameters and derived quantities) from ``LAW_AT``."""
    q = dict(params)
    for d in t.derived:
        q[d.name] = d.value(q)
    args = t.contact.args
    if LAW_AT + len(args) > MAX_PARAMS:
        raise ValueError(f"{t.role}.{t.type_name}: its contact law takes too many quantities")
    row = np.zeros(MAX_PARAMS)
    for i, name in enumerate(PENALTY_P):
        row[i] = float(q.get(name, 0.0))
    row[LAW] = law_index(t.contact)
    for j, name in enumerate(args):
        row[LAW_AT + j] = float(q[name])
    return row


def bearing_params(t: Any, params: Mapping[str, Any]) -> np.ndarray:
    """The parameter row of a bearing of declaration ``t``: its law's index at 0, then the
    quantities the law takes (its parameters and derived quantities)."""
    q = dict(params)
    for d in t.derived:
        q[d.name] = d.value(q)
    row = np.zeros(MAX_PARAMS)
    row[0] = bearing_law.law_index(t.bearing)
    for j, name in enumerate(t.bearing.args):
        row[1 + j] = float(q[name])
    return row


def flat_params(role: str, type_name: str, params: Mapping[str, Any]) -> np.ndarray:
    """The parameter row of a unit (:data:`FLAT_TYPES` order, zero-padded); a penalty
    stator's (:func:`penalty_params`); a bearing's (:func:`bearing_params`); a hybrid
    unit's kernels' array (:func:`.flat_hybrid.hybrid_params`)."""
    t = _penalty_type(role, type_name)
    if t is not None:
        return penalty_params(t, params)
    t = declaration(role, type_name)
    if t is not None and t.bearing is not None:
        return bearing_params(t, params)
    if (role, type_name) not in FLAT_TYPES:
        return hybrid_params(role, type_name, params)
    row = np.zeros(MAX_PARAMS)
    if type_name == "delayed_feedback":
        p = controller_params(params)
        row[: p.size] = p
        return row
    names = FLAT_TYPES[(role, type_name)][2]
    for i, name in enumerate(names):
        row[i] = float(params.get(name, 0.0))
    return row
