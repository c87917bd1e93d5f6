"""The registered unit types, for the modules the registry imports.

The generated dispatches (the hybrid unit types' kernels, the stators' contact laws)
and the co-simulation's unit rows need the list of unit types; the registry
(:mod:`.registry`) imports their modules, so they cannot import it.  The registry
hands its types over here when it is built (:func:`register`), and importing the
package builds it (``components/__init__``): every module of the package finds them
here, with no import back up.
"""

from __future__ import annotations

from typing import Any

_TYPES: list[Any] = []  # the registry's UnitType declarations, in its order


def register(types: tuple[Any, ...]) -> None:
    """The registry's types, in its order (called once, by :mod:`.registry`)."""
    _TYPES[:] = types


def registered() -> tuple[Any, ...]:
    """Every registered unit type (:class:`.declaration.UnitType`), in registry order."""
    if not _TYPES:
        raise RuntimeError("the unit registry is not built (import rubcosim.components first)")
    return tuple(_TYPES)


def declaration(role: str, type_name: str) -> Any:
    """The registered declaration of ``role``/``type_name``, or None."""
    return next((t for t in registered() if t.key == (role, type_name)), None)
