"""Which unit types exist, by role, and their declared parameters (a view of
:data:`.registry.REGISTRY`)."""

from __future__ import annotations

from .parameters import Param
from .registry import REGISTRY

UNIT_TYPES: dict[str, dict[str, tuple[Param, ...]]] = REGISTRY.catalogue()
