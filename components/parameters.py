"""Parameter declarations and validation shared by every unit.

A unit type declares its parameters once, as a tuple of :class:`Param`.  The
scenario loader, the reference assembler and the FMU wrappers read the same
declaration, so a name, unit, default and allowed range live in one place.

Every error raised here is a :class:`ParameterError` whose message names the
field as ``unit.parameter`` and states the allowed values.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


class ParameterError(ValueError):
    """A parameter is unknown, of the wrong type or outside its allowed range."""


@dataclass(frozen=True)
class Param:
    """One declared parameter.

    ``kind`` is ``"real"``, ``"int"``, ``"bool"`` or ``"choice"``.  For reals,
    ``low``/``high`` bound the value; ``low_open``/``high_open`` make a bound
    strict.  ``default=None`` marks a required parameter.
    """

    name: str
    default: Any
    unit: str
    description: str
    kind: str = "real"
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    choices: tuple[str, ...] = ()
    example: Any = None  # a typical value for a required parameter (FMU start values, docs)

    def allowed(self) -> str:
        """Human-readable statement of the allowed values."""
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        lo = "(" if self.low_open else "["
        hi = ")" if self.high_open else "]"
        kind = "an integer" if self.kind == "int" else "a real number"
        return f"{kind} in {lo}{self.low:g}, {self.high:g}{hi}"

    def coerce(self, unit: str, value: Any) -> Any:
        """Return ``value`` converted to this parameter's type, or raise."""
        field = f"{unit}.{self.name}"
        if self.kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                raise ParameterError(f"{field} = {value!r} is not {self.allowed()}")
            return value
        if self.kind == "bool":
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "false"):
                return value.lower() == "true"
            raise ParameterError(f"{field} = {value!r} is not {self.allowed()}")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(f"{field} = {value!r} is not a number; expected {self.allowed()}")
        if isinstance(value, float) and not math.isfinite(value):
            raise ParameterError(f"{field} = {value!r} is not finite; expected {self.allowed()}")
        if self.kind == "int":
            if isinstance(value, float):
                if not value.is_integer():
                    raise ParameterError(
                        f"{field} = {value!r} is not an integer; expected {self.allowed()}"
                    )
                value = int(value)
        else:
            value = float(value)
            if not math.isfinite(value):  # an int too large for a float
                raise ParameterError(
                    f"{field} = {value!r} is not finite; expected {self.allowed()}"
                )
        below = value <= self.low if self.low_open else value < self.low
        above = value >= self.high if self.high_open else value > self.high
        if below or above:
            raise ParameterError(
                f"{field} = {value!r} is outside the allowed range: {self.allowed()}"
            )
        return value


def real(
    name: str,
    default: float | None,
    unit: str,
    description: str,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
    example: float | None = None,
) -> Param:
    return Param(
        name, default, unit, description, "real", low, high, low_open, high_open, example=example
    )


def positive(
    name: str, default: float | None, unit: str, description: str, example: float | None = None
) -> Param:
    return real(name, default, unit, description, 0.0, low_open=True, example=example)


def nonnegative(
    name: str, default: float | None, unit: str, description: str, example: float | None = None
) -> Param:
    return real(name, default, unit, description, 0.0, example=example)


def planar_initial_state(prefix: str, body: str) -> tuple[Param, ...]:
    """The initial state of a planar body: ``{prefix}x0``, ``y0``, ``vx0``, ``vy0`` (m, m/s),
    0 by default; ``body`` names it in the descriptions."""
    return tuple(
        real(f"{prefix}{name}0", 0.0, unit, f"initial {body} {what} along {axis}")
        for name, unit, what, axis in (
            ("x", "m", "displacement", "x"),
            ("y", "m", "displacement", "y"),
            ("vx", "m/s", "velocity", "x"),
            ("vy", "m/s", "velocity", "y"),
        )
    )


def choice(name: str, default: str, description: str, choices: tuple[str, ...]) -> Param:
    return Param(name, default, "", description, "choice", choices=choices)


def resolve(unit: str, specs: tuple[Param, ...], given: Mapping[str, Any]) -> dict[str, Any]:
    """Validate ``given`` against ``specs`` and fill in defaults.

    Unknown names and missing required parameters are errors.
    """
    by_name = {p.name: p for p in specs}
    unknown = sorted(set(given) - set(by_name))
    if unknown:
        known = ", ".join(sorted(by_name))
        raise ParameterError(
            f"{unit}.{unknown[0]} is not a parameter of this unit (known: {known})"
        )
    values: dict[str, Any] = {}
    for p in specs:
        if p.name in given:
            values[p.name] = p.coerce(unit, given[p.name])
        elif p.default is None:
            raise ParameterError(f"{unit}.{p.name} is required ({p.unit}, {p.description})")
        else:
            values[p.name] = p.default
    return values
