"""Connections between units: each input is the sum of zero or more outputs.

Names are ``unit.signal``.  A scenario's ``[connections]`` table maps an input
to a list of outputs (or one output); an empty list disconnects it.  Without
a table, units are connected as their types declare (each unit type's
``wiring``), the way the monolithic reference couples them: the disc state
goes to the stator and the controller, contact and control forces come back
to the disc, the journal state goes to the bearing and its force comes back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

from .registry import REGISTRY


class CouplingError(ValueError):
    """A connection names an unknown unit or signal; the message names it."""


@dataclass(frozen=True)
class Connection:
    """``target`` (``unit.input``) receives the sum of ``sources`` (``unit.output``)."""

    target: str
    sources: tuple[str, ...]

    # split once: the master reads these on every step
    @cached_property
    def unit(self) -> str:
        return self.target.split(".", 1)[0]

    @cached_property
    def input(self) -> str:
        return self.target.split(".", 1)[1]

    @cached_property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        """The sources as (unit, output) pairs."""
        return tuple(tuple(s.split(".", 1)) for s in self.sources)  # type: ignore[misc]


def default_connections(types: Mapping[str, str]) -> list[Connection]:
    """The declared default connections of the units present (``role -> type``): each
    unit type's wiring in :mod:`rubcosim.components.registry`."""
    return [Connection(t, s) for t, s in REGISTRY.default_wiring(types)]


def _split(name: str, where: str) -> tuple[str, str]:
    if not isinstance(name, str) or name.count(".") != 1 or not all(name.split(".")):
        raise CouplingError(f"{where}: {name!r} is not of the form unit.signal")
    unit, signal = name.split(".")
    return unit, signal


def apply_table(connections: Sequence[Connection], table: Mapping[str, object]) -> list[Connection]:
    """Replace or add the connections named in a ``[connections]`` table."""
    merged = {c.target: c for c in connections}
    for target, value in table.items():
        _split(target, "connections")
        sources = [value] if isinstance(value, str) else value
        if not isinstance(sources, list) or not all(isinstance(s, str) for s in sources):
            raise CouplingError(
                f"connections.{target} must be an output name or a list of output names"
            )
        for s in sources:
            _split(s, f"connections.{target}")
        merged[target] = Connection(target, tuple(sources))
    return [c for c in merged.values() if c.sources]


def check_connections(
    connections: Sequence[Connection],
    inputs: Mapping[str, Sequence[str]],
    outputs: Mapping[str, Sequence[str]],
    refused: Mapping[str, Mapping[str, str]] | None = None,
    types: Mapping[str, Mapping[str, str]] | None = None,
) -> None:
    """Every target must be an input and every source an output of a unit present.

    ``refused`` names, per unit, signals it has that cannot be connected, with the
    reason; ``types`` the FMI type of signals (a unit's outputs, a foreign FMU's inputs
    and outputs): an Integer, Boolean or Enumeration input takes only a source of its
    own type."""
    refused = refused or {}
    types = types or {}
    for c in connections:
        _check_refused(c, refused, types)
        unit, signal = _split(c.target, "connections")
        if unit not in inputs:
            raise CouplingError(
                f"connections.{c.target}: no unit {unit!r} (units: {', '.join(inputs)})"
            )
        if signal not in inputs[unit]:
            raise CouplingError(
                f"connections.{c.target}: {signal!r} is not an input of {unit} "
                f"(inputs: {', '.join(inputs[unit])})"
            )
        for s in c.sources:
            su, ss = _split(s, f"connections.{c.target}")
            if su not in outputs:
                raise CouplingError(
                    f"connections.{c.target}: source unit {su!r} is not in the scenario"
                )
            if ss not in outputs[su]:
                raise CouplingError(
                    f"connections.{c.target}: {ss!r} is not an output of {su} "
                    f"(outputs: {', '.join(outputs[su])})"
                )


def _check_refused(
    c: Connection,
    refused: Mapping[str, Mapping[str, str]],
    types: Mapping[str, Mapping[str, str]],
) -> None:
    unit, signal = _split(c.target, "connections")
    for u, sig in [(unit, signal), *(_split(s, f"connections.{c.target}") for s in c.sources)]:
        reason = refused.get(u, {}).get(sig)
        if reason:
            raise CouplingError(f"connections.{c.target}: {u}.{sig} is {reason}")
    wanted = _family(types.get(unit, {}).get(signal, "Real"))
    if wanted == "Real":
        return
    for s in c.sources:
        su, ss = _split(s, f"connections.{c.target}")
        given = _family(types.get(su, {}).get(ss, "Real"))
        if given != wanted:
            raise CouplingError(
                f"connections.{c.target}: {unit}.{signal} is an {wanted} input; "
                f"its source {su}.{ss} is {given}"
            )


def _family(fmi_type: str) -> str:
    """Enumerations are integers (FMI 2.0 sets and gets them with the Integer calls)."""
    return "Integer" if fmi_type == "Enumeration" else fmi_type
