"""What a unit type declares about itself, in one place.

A :class:`UnitType` sits next to its unit class in the unit's module and
states what the rest of the package needs to know about it: the parameters
a scenario gives it, the states it integrates and their scale, what it takes
from its neighbours, what it offers them, its default connections and its
FMU identity.  :mod:`.registry` lists every declaration and derives the unit
catalogue, the FMU list and the default wiring from them.

A declaration checks itself when it is made (a state without a scale, a
need or a wire naming something the unit does not have) and the registry
checks what spans declarations (a wire from an output no neighbour has);
every error is a :class:`DeclarationError` naming the unit type and the
entry.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from .bearing_law import BearingLaw
from .contact_law import ContactLaw
from .hybrid import HybridKernels
from .parameters import Param
from .unit import Signal, Unit

# The scale kinds a state may have, with the unit of measure a state of that kind
# is in.  The reference engines scale their absolute tolerance by the kind's scale
# and the co-simulation sizes coupling errors of signals in that unit by it.
SCALE_KINDS: dict[str, str] = {"length": "m", "velocity": "m/s"}


class DeclarationError(ValueError):
    """A unit type's declaration is inconsistent; the message names the type and entry."""


@dataclass(frozen=True)
class State:
    """A continuous state the unit integrates: ``name`` (the reference calls it
    ``role.name``), its unit of measure, its scale kind (a key of :data:`SCALE_KINDS`)
    and ``initial``, the unit's parameter giving its initial value (empty for a hybrid
    unit type, whose ``initial`` kernel gives the initial state)."""

    name: str
    unit: str
    scale: str
    initial: str = ""


def planar_states(prefix: str = "", initial: str | None = None) -> tuple[State, ...]:
    """Position (m, length scale) and velocity (m/s, velocity scale) of a body in the
    plane: ``x, y, vx, vy``, each name preceded by ``prefix``; their initial values are
    the parameters ``x0, y0, vx0, vy0`` preceded by ``initial`` (default: ``prefix``)."""
    before = prefix if initial is None else initial
    return (
        State(f"{prefix}x", "m", "length", f"{before}x0"),
        State(f"{prefix}y", "m", "length", f"{before}y0"),
        State(f"{prefix}vx", "m/s", "velocity", f"{before}vx0"),
        State(f"{prefix}vy", "m/s", "velocity", f"{before}vy0"),
    )


@dataclass(frozen=True)
class Quantity:
    """A quantity computed from a unit's parameters (``value(params)``, in ``unit``)."""

    name: str
    unit: str
    description: str
    value: Callable[[Mapping[str, Any]], float]


class Provided(Quantity):
    """A quantity the unit offers its neighbours, computed from its own parameters."""


class Derived(Quantity):
    """A quantity the unit's kernels take that no single parameter gives (a force scale,
    a delay given in periods), computed from its parameters and those it takes from its
    neighbours (its :class:`Need` s); the reference packs it next to its parameters."""


@dataclass(frozen=True)
class Need:
    """A parameter the unit takes from a neighbour: its own parameter ``param`` is set
    to ``source`` (``role.quantity``, a :class:`Provided` of the unit in that role).
    With ``reduced_with`` (the name of one of the unit's own mass parameters, kg) the
    value is the reduced mass ``m ms / (m + ms)`` of the source and that parameter."""

    param: str
    source: str
    reduced_with: str = ""


@dataclass(frozen=True)
class Wire:
    """Default connection of the unit's ``input``: the sum of ``sources``
    (``role.output``, in this order); a source whose role is not in the scenario is
    left out, and with none left the input stays unconnected."""

    input: str
    sources: tuple[str, ...]


@dataclass(frozen=True)
class FmuIdentity:
    """The FMU built from the unit: its FMI model identifier (also its file's name)."""

    identifier: str

    @property
    def file_name(self) -> str:
        return f"{self.identifier}.fmu"


@dataclass(frozen=True)
class UnitType:
    """One unit type.  Role, type name, summary, inputs and outputs are those of its
    ``unit_class`` (written once, on the class).

    ``params``: what a scenario gives it (the catalogue; the class may declare more,
    set from neighbours or settings).  ``states``: its continuous states, each with an
    explicit scale.  ``needs``/``provides``: parameters taken from and quantities
    offered to neighbours.  ``wiring``: its inputs' default connections.
    ``derived``: quantities its kernels take, computed from its parameters.
    ``kernels``: the compiled functions holding its physics (shared with the
    reference).  ``mass_scale``: the parameter (kg) that sizes the forces the
    scenario's units exchange (force scale = mass * velocity scale**2 / length scale).
    ``length_scale(params)``: a length (m) the motion is measured against (a
    clearance, an unbalance); the model's length scale is the largest.  ``clock(params)``:
    for the unit that drives the model, ``(forcing frequency, frequency scale)`` in
    rad/s: the forcing period is 2 pi over the first, the velocity scale the length
    scale times the second (see :mod:`.graph`).  ``hybrid``: the kernels of a unit
    type that is a whole nonsmooth model (:mod:`.hybrid`); the reference compiles
    them, the unit class steps them.  ``contact``: a stator type's contact law
    (:mod:`.contact_law`), which fixes its event protocol in every engine and, for a
    penalty contact, its normal force.  ``bearing``: a bearing type's force law on
    the journal (:mod:`.bearing_law`), which every engine calls.
    """

    unit_class: type[Unit]
    params: tuple[Param, ...]
    fmu: FmuIdentity
    states: tuple[State, ...] = ()
    needs: tuple[Need, ...] = ()
    provides: tuple[Provided, ...] = ()
    wiring: tuple[Wire, ...] = ()
    derived: tuple[Derived, ...] = ()
    kernels: tuple[Callable[..., Any], ...] = ()
    mass_scale: str = ""
    length_scale: Callable[[Mapping[str, Any]], float] | None = None
    clock: Callable[[Mapping[str, Any]], tuple[float, float]] | None = None
    hybrid: HybridKernels | None = None
    contact: ContactLaw | None = None
    bearing: BearingLaw | None = None

    @property
    def role(self) -> str:
        return self.unit_class.role

    @property
    def type_name(self) -> str:
        return self.unit_class.type_name

    @property
    def key(self) -> tuple[str, str]:
        return self.role, self.type_name

    @property
    def summary(self) -> str:
        return self.unit_class.summary

    @property
    def inputs(self) -> tuple[Signal, ...]:
        return self.unit_class.inputs

    @property
    def outputs(self) -> tuple[Signal, ...]:
        return self.unit_class.outputs

    def _example_params(self) -> dict[str, Any]:
        return self.unit_class.example_params()

    def provided(self, name: str) -> Provided | None:
        return next((p for p in self.provides if p.name == name), None)

    def __post_init__(self) -> None:
        where = f"{self.role}.{self.type_name}"

        def fail(message: str) -> None:
            raise DeclarationError(f"unit type {where}: {message}")

        class_params = {p.name for p in self.unit_class.params_spec}
        for p in self.params:
            if p.name not in class_params:
                fail(f"parameter {p.name!r} is not one of {self.unit_class.__name__}'s")
        for s in self.states:
            if s.scale not in SCALE_KINDS:
                kinds = ", ".join(SCALE_KINDS)
                fail(f"state {s.name!r} has no scale (scale = {s.scale!r}; one of {kinds})")
            if s.unit != SCALE_KINDS[s.scale]:
                expected = SCALE_KINDS[s.scale]
                fail(f"state {s.name!r} is in {s.unit!r} but a {s.scale} is in {expected!r}")
            if s.initial and s.initial not in class_params:
                fail(f"state {s.name!r}: its initial value {s.initial!r} is not a parameter")
        for d in self.derived:
            if d.name in class_params:
                fail(f"derived quantity {d.name!r} has the name of a parameter")
        for n in self.needs:
            for name in filter(None, (n.param, n.reduced_with)):
                if name not in class_params:
                    fail(f"need {n.param!r}: {name!r} is not a parameter of the unit")
            _split(n.source, f"{where}: need {n.param!r}")
        inputs = {s.name for s in self.inputs}
        for w in self.wiring:
            if w.input not in inputs:
                fail(f"wire to {w.input!r}: not an input of the unit")
            for s in w.sources:
                _split(s, f"{where}: wire to {w.input!r}")
        if self.mass_scale and self.mass_scale not in class_params:
            fail(f"mass_scale {self.mass_scale!r} is not a parameter of the unit")
        for k in self.kernels:
            if not callable(k):
                fail(f"kernel {k!r} is not callable")
        if self.hybrid is not None:
            names = [s.name for s in self.outputs]
            expected = (*self.hybrid.outputs, "impacts", "mode")
            if names[: len(self.hybrid.outputs)] != list(self.hybrid.outputs) or not {
                "impacts",
                "mode",
            } <= set(names):
                fail(f"the unit's outputs must start with the hybrid kernels' {expected}")
            if len(self.states) != len(self.hybrid.initial(self._example_params())[0]):
                fail("the hybrid kernels' state does not match the declared states")
        known = {*class_params, *(n.param for n in self.needs), *(d.name for d in self.derived)}
        for what, law in (("contact law", self.contact), ("bearing law", self.bearing)):
            for name in law.args if law is not None else ():
                if name not in known:
                    fail(f"{what}: {name!r} is not a parameter or derived quantity")
        if not self.fmu.identifier.isidentifier():
            fail(f"FMU identifier {self.fmu.identifier!r} is not an identifier")


def _split(name: str, where: str) -> tuple[str, str]:
    """``role.name`` as a pair; anything else is a DeclarationError naming ``where``."""
    parts = name.split(".") if isinstance(name, str) else []
    if len(parts) != 2 or not all(parts):
        raise DeclarationError(f"unit type {where}: {name!r} is not of the form role.name")
    return parts[0], parts[1]
