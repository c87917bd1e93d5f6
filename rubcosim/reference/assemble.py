"""Assemble validated units into one monolithic system (the ``p``/``ip`` arrays)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcosim.components.declaration import Derived
from rubcosim.components.graph import ModelGraph, UnitNode, model_scales
from rubcosim.components.hybrid_dispatch import hybrid_types
from rubcosim.components.parameters import ParameterError
from rubcosim.components.registry import REGISTRY

from . import system as S
from .layout import LAYOUT
from .system_outputs import output_names

# Relative size of the rebound normal speed (to the system's velocity scale)
# below which chattering is declared over and the contact becomes sustained.
DEFAULT_CHATTER_TOL = 1e-10


@dataclass
class System:
    """A monolithic system ready for either engine."""

    family: int
    p: np.ndarray
    ip: np.ndarray
    y0: np.ndarray
    mode0: int
    state_names: list[str]
    state_scale: np.ndarray
    output_names: list[str]
    forcing_period: float
    velocity_scale: float
    units: dict[str, UnitNode] = field(default_factory=dict)

    @property
    def n_state(self) -> int:
        return int(self.y0.shape[0])

    @property
    def has_delay(self) -> bool:
        return self.family == S.FAMILY_ROTOR and self.ip[S.IP_CONTROLLER] != S.CONTROLLER_NONE

    def min_delay(self) -> float:
        if not self.has_delay:
            return math.inf
        return float(
            self.p[S.P_CONTROLLER_BASE_DELAY] - self.p[S.P_CONTROLLER_MODULATION_AMPLITUDE]
        )


def _state_scale(
    units: Mapping[str, UnitNode], names: list[str], length: float, vscale: float
) -> np.ndarray:
    """Each state's scale (m or m/s) from the scale kind its unit type declares."""
    kinds = REGISTRY.state_scales({role: u.type for role, u in units.items()})
    by_kind = {"length": length, "velocity": vscale}
    return np.array([by_kind[kinds[name]] for name in names])


def build_system(
    model: ModelGraph | Mapping[str, UnitNode], chatter_tol: float = DEFAULT_CHATTER_TOL
) -> System:
    """Compile a model (its graph, or just its units) into one monolithic system.

    The rotor's disc carries the unbalance, the stator contact and the
    controller force; the bearing acts on the journal of a two-mass rotor.
    """
    units = model.units if isinstance(model, ModelGraph) else dict(model)
    whole = [u for u in units.values() if u.declaration.hybrid is not None]
    if whole:
        extra = sorted(set(units) - {whole[0].role})
        if extra:
            raise ParameterError(
                f"unit {extra[0]!r} cannot be combined with {whole[0].role}.type = "
                f"{whole[0].type!r}, a whole model"
            )
        return _hybrid_system(whole[0], chatter_tol)
    if "rotor" not in units:
        raise ParameterError("the scenario needs a 'rotor' or an 'oscillator' unit")
    return _rotor_system(units, chatter_tol)


def _hybrid_system(u: UnitNode, chatter_tol: float) -> System:
    """A hybrid unit type's kernels as the system (:mod:`rubcosim.components.hybrid_dispatch`)."""
    declared = u.declaration
    kernels = declared.hybrid
    params = {**u.params, "chatter_tol": chatter_tol}
    y0, mode0 = kernels.initial(params)
    packed = kernels.parameters(params)  # no inputs: the unit is the whole model
    p, ip = LAYOUT.new_arrays(packed.size)
    p[: packed.size] = packed
    ip[S.IP_FAMILY] = S.FAMILY_HYBRID + hybrid_types().index(declared)
    ip[S.IP_NSTATE] = len(y0)
    scales = model_scales({u.role: u})
    names = [f"{u.role}.{s.name}" for s in declared.states]
    return System(
        family=int(ip[S.IP_FAMILY]),
        p=p,
        ip=ip,
        y0=np.array(y0, dtype=float),
        mode0=int(mode0),
        state_names=names,
        state_scale=_state_scale({u.role: u}, names, scales.length, scales.velocity),
        output_names=output_names(ip),
        forcing_period=scales.forcing_period,
        velocity_scale=scales.velocity,
        units={u.role: u},
    )


def _check_rotor_model(units: Mapping[str, UnitNode]) -> None:
    """What no single unit's parameters can say: a bearing holds the journal of a
    two-mass rotor, the oil film needs spin, the journal and disc start inside."""
    r = units["rotor"].params
    stator, bearing = units.get("stator"), units.get("bearing")
    # a rotor with a journal (the two-mass rotor) is held by a bearing
    two_mass = any(st.name == "journal_x" for st in units["rotor"].declaration.states)
    if bearing is not None and not two_mass:
        raise ParameterError(
            "bearing: a bearing needs rotor.type = 'two_mass' (it holds the journal)"
        )
    if two_mass and bearing is None:
        raise ParameterError("rotor.type = 'two_mass' needs a 'bearing' unit for its journal")
    if bearing is not None and bearing.declaration.bearing is not None:
        _check_bearing_law(units)
    if stator is not None and stator.declaration.contact.kind == "rigid":
        s = stator.params
        if math.hypot(r["x0"] - s["x_offset"], r["y0"] - s["y_offset"]) > s["clearance"]:
            raise ParameterError(
                "rotor.x0/rotor.y0 start the disc beyond the rigid stator's clearance "
                "(stator.clearance about stator.x_offset/stator.y_offset)"
            )


def _check_bearing_law(units: Mapping[str, UnitNode]) -> None:
    """What the bearing type's law declares (:class:`~rubcosim.components.bearing_law.
    BearingLaw`): its ``positive`` quantities are > 0, and the journal it holds starts
    inside its ``wall``."""
    bearing = units["bearing"]
    law = bearing.declaration.bearing
    q = kernel_values(units)["bearing"]
    sources = {n.param: n.source for n in bearing.declaration.needs}
    for name in law.positive:
        if not q[name] > 0.0:
            where = sources.get(name, f"bearing.{name}")
            raise ParameterError(f"{where} must be > 0 with {law.model} (bearing)")
    if law.wall:
        # the journal's initial position: the parameters giving the initial values of
        # the rotor states the bearing's x and y inputs are wired to
        initial = {f"rotor.{s.name}": s.initial for s in units["rotor"].declaration.states}
        wired = {w.input: w.sources[0] for w in bearing.declaration.wiring}
        names = [initial.get(wired.get(axis, ""), "") for axis in ("x", "y")]
        r = units["rotor"].params
        if all(names) and math.hypot(r[names[0]], r[names[1]]) >= q[law.wall]:
            raise ParameterError(
                f"rotor.{names[0]}/{names[1]} put the journal outside {law.model}'s "
                f"{law.wall} (bearing.{law.wall})"
            )


def kernel_values(units: Mapping[str, UnitNode]) -> dict[str, dict[str, Any]]:
    """role -> what the kernels take of that unit: its parameters, those it takes from
    its neighbours and its derived quantities (as its type declares them)."""
    types = {role: u.type for role, u in units.items()}
    neighbours = REGISTRY.neighbour_params(types, {r: u.params for r, u in units.items()})
    values = {}
    for role, u in units.items():
        q = {**u.params, **neighbours.get(role, {})}
        for d in u.declaration.derived:
            q[d.name] = _derived_value(role, u, d, q)
        values[role] = q
    return values


def _derived_value(role: str, u: UnitNode, d: Derived, q: Mapping[str, Any]) -> float:
    """``d``'s value for the unit in ``role``; a ParameterError naming the unit's
    parameters when they make it overflow or not a finite number (each in its range, a
    product of them can still pass 1e308)."""
    try:
        value = d.value(q)
    except (OverflowError, ZeroDivisionError):
        value = math.inf
    if not math.isfinite(value):
        names = ", ".join(f"{role}.{k}" for k in u.params)
        raise ParameterError(
            f"{role}: its {d.name} ({d.description}) is not a finite number; check {names}"
        )
    return value


def _rotor_system(units: Mapping[str, UnitNode], chatter_tol: float) -> System:
    """The rotor family's system: every unit packed at the slots its declaration gives
    (:mod:`.layout`), its states after those of the roles before it."""
    _check_rotor_model(units)
    values = kernel_values(units)
    p, ip = LAYOUT.new_arrays()
    ip[S.IP_FAMILY] = S.FAMILY_ROTOR
    names, y0 = [], []
    for role in LAYOUT.roles:
        if role not in units:
            continue
        declared = units[role].declaration
        LAYOUT.pack(role, declared, values[role], p, ip)
        for s in declared.states:
            ip[LAYOUT.ip_state[(role, s.name)]] = len(y0)
            names.append(f"{role}.{s.name}")
            y0.append(values[role][s.initial])
    scales = model_scales(units)
    p[S.P_VCHAT] = chatter_tol * scales.velocity
    p[S.P_OMEGA_B] = scales.frequency
    ip[S.IP_NSTATE] = len(y0)
    return System(
        family=S.FAMILY_ROTOR,
        p=p,
        ip=ip,
        y0=np.array(y0, dtype=float),
        mode0=S.MODE_FREE,
        state_names=names,
        state_scale=_state_scale(units, names, scales.length, scales.velocity),
        output_names=output_names(ip),
        forcing_period=scales.forcing_period,
        velocity_scale=scales.velocity,
        units=dict(units),
    )
