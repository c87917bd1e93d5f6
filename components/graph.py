"""The model graph: the units of a model and how they are connected, no numbers packed.

A scenario builds one :class:`ModelGraph`; the monolithic reference compiles
it into its system (:func:`rubcosim.reference.assemble.build_system`), the
co-simulation instantiates its units and connections
(:mod:`rubcosim.orchestrator.assembly`), and the analyses take it through
the scenario.  Every unit is a :class:`UnitNode` holding its validated
parameters; what the graph knows beyond them (default wiring, the model's
scales) comes from the unit types' declarations (:mod:`.registry`).

Foreign units (FMUs that are not rubcosim's) join the graph by their signal
names only: they can be wired, not compiled into the reference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from .declaration import UnitType
from .parameters import ParameterError, resolve
from .registry import REGISTRY
from .wiring import Connection, apply_table, check_connections, default_connections

DEFAULT_LENGTH = 1e-3  # m: the length scale of a model no unit gives one to


@dataclass(frozen=True)
class UnitNode:
    """A unit of the model: its role (also its name), its type and its parameters
    (validated, defaults filled in; SI units)."""

    role: str
    type: str
    params: dict[str, Any]

    @property
    def declaration(self) -> UnitType:
        return REGISTRY.get(self.role, self.type)


@dataclass(frozen=True)
class Scales:
    """The model's scales: ``length`` (m) the largest a unit declares, ``frequency``
    (rad/s) the driving unit's frequency scale, ``velocity = length * frequency``
    (m/s) and ``forcing_period`` (s).  The engines scale absolute tolerances and the
    end of chattering by them, the co-simulation its coupling errors."""

    length: float
    frequency: float
    forcing_period: float

    @property
    def velocity(self) -> float:
        return self.length * self.frequency


def make_node(role: str, type_name: Any, given: Mapping[str, Any]) -> UnitNode:
    """Validate one unit's parameters (unknown, missing, wrong type, out of range); every
    error is a :class:`.parameters.ParameterError` naming ``role.key``."""
    kinds = REGISTRY.catalogue()
    if role not in kinds:
        raise ParameterError(f"unit {role!r} is not known (known units: {', '.join(kinds)})")
    if not isinstance(type_name, str) or type_name not in kinds[role]:
        raise ParameterError(f"{role}.type = {type_name!r} is not one of {', '.join(kinds[role])}")
    return UnitNode(role, type_name, resolve(role, kinds[role][type_name], given))


def _fmi_type(kind: str) -> str:
    """The FMI type of a declared signal kind ("real" or "integer")."""
    return "Integer" if kind == "integer" else "Real"


@dataclass(frozen=True)
class ForeignNode:
    """A unit known only by its signals (a foreign FMU)."""

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    # signals it has but that cannot be connected, with the reason (a String variable)
    refused: Mapping[str, str] = field(default_factory=dict)
    # FMI type of each signal; an Integer, Boolean or Enumeration input takes only a
    # source of its own type
    types: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ModelGraph:
    """Units (``role -> UnitNode``), foreign units and the resolved connections."""

    units: dict[str, UnitNode]
    connections: tuple[Connection, ...]
    foreign: dict[str, ForeignNode] = field(default_factory=dict)

    @property
    def types(self) -> dict[str, str]:
        """``role -> type`` of the model's own units."""
        return {role: u.type for role, u in self.units.items()}

    @property
    def params(self) -> dict[str, dict[str, Any]]:
        return {role: u.params for role, u in self.units.items()}

    @cached_property
    def scales(self) -> Scales:
        return model_scales(self.units)


def model_scales(units: Mapping[str, UnitNode]) -> Scales:
    """The scales of a model of ``units``, from their declarations (see :class:`Scales`):
    the largest declared length (``DEFAULT_LENGTH`` if none), the driving unit's clock."""
    lengths = [
        u.declaration.length_scale(u.params)
        for u in units.values()
        if u.declaration.length_scale is not None
    ]
    length = max(lengths, default=0.0)
    if length <= 0.0:
        length = DEFAULT_LENGTH
    clocks = [u for u in units.values() if u.declaration.clock is not None]
    if not clocks:
        raise ParameterError(
            "the model has no unit that drives it (a rotor or an oscillator) to give it a "
            "forcing period"
        )
    forcing, frequency = clocks[0].declaration.clock(clocks[0].params)
    return Scales(length, frequency, 2.0 * math.pi / forcing)


def build_graph(
    units: Mapping[str, UnitNode],
    table: Mapping[str, object] | None = None,
    foreign: Sequence[ForeignNode] = (),
) -> ModelGraph:
    """The graph of ``units`` wired as their types declare, with a scenario's
    ``[connections]`` table on top (it replaces or adds connections; ``[]``
    disconnects an input); every connection is checked against the signals present
    (a :class:`.wiring.CouplingError` names a bad one)."""
    types = {role: u.type for role, u in units.items()}
    connections = apply_table(default_connections(types), table or {})
    declared = {role: u.declaration for role, u in units.items()}
    check_connections(
        connections,
        {
            **{r: [s.name for s in d.inputs] for r, d in declared.items()},
            **{f.name: list(f.inputs) for f in foreign},
        },
        {
            **{r: [s.name for s in d.outputs] for r, d in declared.items()},
            **{f.name: list(f.outputs) for f in foreign},
        },
        refused={f.name: f.refused for f in foreign},
        types={
            **{r: {s.name: _fmi_type(s.kind) for s in d.outputs} for r, d in declared.items()},
            **{f.name: f.types for f in foreign},
        },
    )
    return ModelGraph(dict(units), tuple(connections), {f.name: f for f in foreign})
