"""Every unit type, once; the catalogue, the FMU list and the default wiring follow.

Adding a unit type: declare a :class:`.declaration.UnitType` next to its class in
its module and list it in :data:`REGISTRY` below.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from .anisotropic_bearing import ANISOTROPIC_BEARING
from .bearing_unit import LINEAR_BEARING, OILFILM_BEARING
from .controller_unit import DELAYED_FEEDBACK
from .declaration import DeclarationError, UnitType, Wire
from .hunt_crossley import HUNT_CROSSLEY_STATOR
from .oscillator_unit import IMPACT_OSCILLATOR
from .parameters import Param
from .registered import register
from .rotor_unit import JEFFCOTT_ROTOR, TWO_MASS_ROTOR
from .stator import reduced_mass
from .stator_unit import CASING_STATOR, ELASTIC_STATOR, RIGID_STATOR
from .two_dof_oscillator import TWO_DOF_IMPACT_OSCILLATOR
from .unit import Unit


class Registry:
    """The declared unit types, in a stable order (roles in order of first appearance),
    checked against each other: every wire's source must be an output, and every need's
    source a provided quantity, of some type of the role it names."""

    def __init__(self, types: tuple[UnitType, ...]) -> None:
        self.types = types
        self._by_key: dict[tuple[str, str], UnitType] = {}
        for t in types:
            if t.key in self._by_key:
                raise DeclarationError(f"unit type {t.role}.{t.type_name} is declared twice")
            self._by_key[t.key] = t
        for t in types:
            self._check_neighbours(t)

    def _of_role(self, role: str) -> list[UnitType]:
        return [t for t in self.types if t.role == role]

    def _check_neighbours(self, t: UnitType) -> None:
        where = f"unit type {t.role}.{t.type_name}"
        for w in t.wiring:
            for source in w.sources:
                role, output = source.split(".")
                if not any(output in {s.name for s in n.outputs} for n in self._of_role(role)):
                    raise DeclarationError(
                        f"{where}: wire to {w.input!r} from {source!r}: no {role} type has "
                        f"an output {output!r}"
                    )
        for need in t.needs:
            role, name = need.source.split(".")
            if not any(n.provided(name) for n in self._of_role(role)):
                raise DeclarationError(
                    f"{where}: need {need.param!r} from {need.source!r}: no {role} type "
                    f"provides {name!r}"
                )

    def __iter__(self) -> Iterator[UnitType]:
        return iter(self.types)

    def get(self, role: str, type_name: str) -> UnitType | None:
        return self._by_key.get((role, type_name))

    def catalogue(self) -> dict[str, dict[str, tuple[Param, ...]]]:
        """role -> type -> the parameters a scenario gives it."""
        out: dict[str, dict[str, tuple[Param, ...]]] = {}
        for t in self.types:
            out.setdefault(t.role, {})[t.type_name] = t.params
        return out

    def classes(self) -> dict[tuple[str, str], type[Unit]]:
        return {t.key: t.unit_class for t in self.types}

    def _wiring(self, role: str, type_name: str) -> tuple[Wire, ...]:
        t = self.get(role, type_name)
        if t is not None:
            return t.wiring
        # A type not declared here (a stand-in in a test, a scenario not yet checked)
        # gets the wires every declared type of its role has.
        kinds = self._of_role(role)
        if not kinds:
            return ()
        return tuple(w for w in kinds[0].wiring if all(w in k.wiring for k in kinds[1:]))

    def default_wiring(self, types: Mapping[str, str]) -> list[tuple[str, tuple[str, ...]]]:
        """``(role.input, sources)`` for the units present (``role -> type``), in the order
        of ``types`` and of each type's wires; sources from absent roles are left out."""
        links = []
        for role, type_name in types.items():
            for w in self._wiring(role, type_name):
                sources = tuple(s for s in w.sources if s.split(".")[0] in types)
                if sources:
                    links.append((f"{role}.{w.input}", sources))
        return links

    def neighbour_params(
        self, types: Mapping[str, str], params: Mapping[str, Mapping[str, Any]]
    ) -> dict[str, dict[str, Any]]:
        """For every unit present, the parameters it takes from its neighbours (their
        :class:`.declaration.Provided` quantities, computed from ``params[role]``)."""
        out: dict[str, dict[str, Any]] = {}
        for role, type_name in types.items():
            t = self.get(role, type_name)
            for need in t.needs if t is not None else ():
                source_role, name = need.source.split(".")
                if source_role not in types:
                    continue
                source = self.get(source_role, types[source_role])
                provided = source.provided(name) if source is not None else None
                if provided is None:
                    raise DeclarationError(
                        f"{role}.{need.param} comes from {need.source}, which "
                        f"{source_role}.type = {types[source_role]!r} does not provide"
                    )
                value = provided.value(params[source_role])
                if need.reduced_with:
                    value = reduced_mass(value, params[role][need.reduced_with])
                out.setdefault(role, {})[need.param] = value
        return out

    def state_scales(self, types: Mapping[str, str]) -> dict[str, str]:
        """``role.state`` -> scale kind for every state of the units present."""
        return {
            f"{role}.{s.name}": s.scale
            for role, type_name in types.items()
            for s in self._by_key[(role, type_name)].states
        }

    def mass_scale(
        self, types: Mapping[str, str], params: Mapping[str, Mapping[str, Any]]
    ) -> float:
        """The mass (kg) that sizes the forces between the units present: the first unit
        declaring a ``mass_scale``, else 1."""
        for role, type_name in types.items():
            t = self.get(role, type_name)
            if t is not None and t.mass_scale:
                return float(params[role][t.mass_scale])
        return 1.0


REGISTRY = Registry(
    (
        JEFFCOTT_ROTOR,
        TWO_MASS_ROTOR,
        RIGID_STATOR,
        ELASTIC_STATOR,
        CASING_STATOR,
        HUNT_CROSSLEY_STATOR,
        OILFILM_BEARING,
        LINEAR_BEARING,
        ANISOTROPIC_BEARING,
        DELAYED_FEEDBACK,
        IMPACT_OSCILLATOR,
        TWO_DOF_IMPACT_OSCILLATOR,
    )
)
register(REGISTRY.types)  # for the modules below the registry (.registered)
