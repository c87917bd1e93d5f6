"""Every unit class, by role and type (the same keys as :data:`.catalog.UNIT_TYPES`)."""

from __future__ import annotations

from typing import Any

from .bearing_unit import LinearBearingUnit, OilFilmBearingUnit
from .controller_unit import DelayedFeedbackUnit
from .oscillator_unit import ImpactOscillatorUnit
from .parameters import ParameterError
from .rotor_unit import JeffcottRotorUnit, TwoMassRotorUnit
from .stator_unit import CasingStatorUnit, ElasticStatorUnit, RigidStatorUnit
from .unit import Unit

UNIT_CLASSES: dict[tuple[str, str], type[Unit]] = {
    (cls.role, cls.type_name): cls
    for cls in (
        JeffcottRotorUnit,
        TwoMassRotorUnit,
        RigidStatorUnit,
        ElasticStatorUnit,
        CasingStatorUnit,
        OilFilmBearingUnit,
        LinearBearingUnit,
        DelayedFeedbackUnit,
        ImpactOscillatorUnit,
    )
}


def unit_class(role: str, type_name: str, name: str | None = None) -> type[Unit]:
    """The class for ``role``/``type_name``; an unknown one is a ParameterError."""
    cls = UNIT_CLASSES.get((role, type_name))
    if cls is None:
        known = sorted(t for r, t in UNIT_CLASSES if r == role)
        raise ParameterError(f"{name or role}.type = {type_name!r} is not one of {known}")
    return cls


def make_unit(role: str, type_name: str, name: str | None = None, **params: Any) -> Unit:
    """Build the unit for ``role``/``type_name`` from ``params`` (required ones must be given)."""
    return unit_class(role, type_name, name)(name=name, **params)
