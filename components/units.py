"""Every unit class, by role and type (the same keys as :data:`.catalog.UNIT_TYPES`), as
declared in :data:`.registry.REGISTRY`."""

from __future__ import annotations

from typing import Any

from .declaration import UnitType
from .parameters import ParameterError
from .registry import REGISTRY
from .unit import Unit

UNIT_CLASSES: dict[tuple[str, str], type[Unit]] = REGISTRY.classes()


def unit_type(role: str, type_name: str, name: str | None = None) -> UnitType:
    """The declaration of ``role``/``type_name``; an unknown one is a ParameterError."""
    declared = REGISTRY.get(role, type_name)
    if declared is None:
        known = sorted(t for r, t in UNIT_CLASSES if r == role)
        raise ParameterError(f"{name or role}.type = {type_name!r} is not one of {known}")
    return declared


def unit_class(role: str, type_name: str, name: str | None = None) -> type[Unit]:
    """The class for ``role``/``type_name``; an unknown one is a ParameterError."""
    return unit_type(role, type_name, name).unit_class


def make_unit(role: str, type_name: str, name: str | None = None, **params: Any) -> Unit:
    """Build the unit for ``role``/``type_name`` from ``params`` (required ones must be given)."""
    return unit_class(role, type_name, name)(name=name, **params)
