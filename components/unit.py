"""One co-simulation unit: declared signals, a step, and a state that can be saved.

A :class:`Unit` is the in-process form of a subsystem.  The FMU wrappers in
``rubcosim.fmus`` expose exactly these declarations as FMI variables, and the
orchestrator's ``direct`` backend steps the same objects without FMI, so the
two backends cannot drift apart.

Contract of every unit:

* parameters are declared once (:mod:`.parameters`) and validated when the
  unit is built; a bad value raises :class:`ParameterError` naming
  ``unit.parameter``;
* an input is a polynomial over a step: its value at the step's start,
  plus optional first and second time derivatives set by the master
  (:meth:`Unit.set_input_derivative`, FMI 2.0's ``fmi2SetRealInputDerivatives``);
  setting a value clears its derivatives, so a plain ``set_input`` holds the
  input constant (zero-order hold);
* :meth:`Unit.do_step` either completes the step or raises :class:`StepError`
  with the unit's state left exactly as it was before the call;
* :meth:`Unit.get_state` captures everything the next step depends on
  (continuous state, inputs, integrator step size, counters, history
  buffers), so restoring a snapshot and stepping again is bit-identical.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .kernels import polynomial_at
from .parameters import Param, real, resolve


class StepError(RuntimeError):
    """A step could not be completed; the unit's state is what it was before the step."""


class OutputError(StepError, ValueError):
    """The state a step reached has no valid outputs (e.g. a journal outside its oil
    film): a failed step to a master, a bad value to anyone else."""


@dataclass(frozen=True)
class Signal:
    """An input or output of a unit: name, unit of measure, meaning, type and start value."""

    name: str
    unit: str
    description: str
    kind: str = "real"  # "real" or "integer"
    start: float = 0.0


def real_signal(name: str, unit: str, description: str, start: float = 0.0) -> Signal:
    return Signal(name, unit, description, "real", start)


def integer_signal(name: str, description: str, start: int = 0) -> Signal:
    return Signal(name, "", description, "integer", start)


def planar_motion(body: str, prefix: str = "") -> tuple[Signal, ...]:
    """Position and velocity of a body in the plane: ``x, y, vx, vy`` (m, m/s), each name
    preceded by ``prefix``."""
    return (
        real_signal(f"{prefix}x", "m", f"{body} displacement along x"),
        real_signal(f"{prefix}y", "m", f"{body} displacement along y"),
        real_signal(f"{prefix}vx", "m/s", f"{body} velocity along x"),
        real_signal(f"{prefix}vy", "m/s", f"{body} velocity along y"),
    )


INTEGRATOR_PARAMS = (
    real("rtol", 1e-10, "1", "relative tolerance of the unit's internal integrator", 1e-14, 1e-2),
    real("atol", 1e-14, "1", "absolute tolerance of the internal integrator (state units)", 0.0),
)


class Unit:
    """Base class: subclasses declare ``role``, ``type_name``, ``params_spec``,
    ``inputs``, ``outputs`` and implement ``_initial_state``, ``_advance`` and
    ``_outputs``.

    All mutable state lives in ``self.state`` (a dict of floats, ints and
    numpy arrays) and ``self.u`` (input values), which is what a snapshot
    copies.
    """

    role: ClassVar[str]
    type_name: ClassVar[str]
    summary: ClassVar[str]
    protocol: ClassVar[str] = ""  # how a master drives its events, for FMU descriptions
    # whether outputs depend on the inputs at the same instant (a master orders units by it)
    feedthrough: ClassVar[bool] = True
    # whether a zero-length step just before an event records the inputs' left limits
    records_left_limits: ClassVar[bool] = False
    params_spec: ClassVar[tuple[Param, ...]]
    inputs: ClassVar[tuple[Signal, ...]]
    outputs: ClassVar[tuple[Signal, ...]]

    def __init__(self, name: str | None = None, **params: Any) -> None:
        self.name = name or self.role
        self.params = resolve(self.name, self.params_spec, params)
        self._check(self.params)
        self.u: dict[str, float] = {s.name: s.start for s in self.inputs}
        self.du: dict[str, tuple[float, float]] = {}
        self.time = 0.0
        self.state: dict[str, Any] = self._initial_state()

    @classmethod
    def example_params(cls) -> dict[str, Any]:
        """Every parameter at its default, or at its example value where it is required."""
        return {p.name: p.default if p.default is not None else p.example for p in cls.params_spec}

    @classmethod
    def example(cls, name: str | None = None, **overrides: Any) -> Unit:
        """A unit built from :meth:`example_params` with ``overrides``."""
        return cls(name=name, **{**cls.example_params(), **overrides})

    # --- to implement -------------------------------------------------------
    def _check(self, params: Mapping[str, Any]) -> None:
        """Cross-parameter checks beyond each parameter's own range."""

    def _initial_state(self) -> dict[str, Any]:
        raise NotImplementedError

    def _advance(self, t: float, h: float) -> None:
        raise NotImplementedError

    def _outputs(self) -> dict[str, float]:
        raise NotImplementedError

    # --- public API -----------------------------------------------------------
    def reset(self, start_time: float = 0.0) -> None:
        """Back to the initial state at ``start_time``; inputs back to their start values."""
        self.u = {s.name: s.start for s in self.inputs}
        self.du = {}
        self.time = float(start_time)
        self.state = self._initial_state()

    def set_input(self, name: str, value: float) -> None:
        """Set one input; an unknown name is an error naming the unit."""
        if name not in self.u:
            known = ", ".join(self.u)
            raise KeyError(f"{self.name}.{name} is not an input (inputs: {known})")
        self.u[name] = value
        self.du.pop(name, None)

    def set_input_derivative(self, name: str, order: int, value: float) -> None:
        """Set the ``order``-th time derivative (1 or 2) of a real input at the start of
        the next step, in the input's unit per second**order."""
        if name not in self.u:
            raise KeyError(f"{self.name}.{name} is not an input")
        if order not in (1, 2):
            raise ValueError(f"{self.name}.{name}: derivative order {order!r} is not 1 or 2")
        if not math.isfinite(value):
            raise ValueError(f"{self.name}.{name}: derivative {value!r} is not finite")
        d1, d2 = self.du.get(name, (0.0, 0.0))
        self.du[name] = (value, d2) if order == 1 else (d1, value)

    def set_input_polynomial(self, name: str, value: float, d1: float, d2: float) -> None:
        """Set an input's value and its first two time derivatives at the start of the
        next step in one call (what a master with input extrapolation does every step)."""
        if name not in self.u:
            raise KeyError(f"{self.name}.{name} is not an input")
        if not (math.isfinite(d1) and math.isfinite(d2)):
            raise ValueError(f"{self.name}.{name}: derivatives {d1!r}, {d2!r} are not finite")
        self.u[name] = value
        self.du[name] = (d1, d2)

    def set_input_polynomials(self, rows: Mapping[str, tuple[float, float, float]]) -> None:
        """:meth:`set_input_polynomial` for several inputs: ``{name: (value, d1, d2)}``."""
        for name, (value, d1, d2) in rows.items():
            self.set_input_polynomial(name, value, d1, d2)

    def input_at(self, name: str, t: float) -> float:
        """Value of an input at time ``t`` inside the current step (its polynomial)."""
        d = self.du.get(name)
        if d is None:
            return self.u[name]
        return polynomial_at(self.u[name], d[0], d[1], t - self.time)

    def input_rows(self, names: tuple[str, ...]) -> np.ndarray:
        """The polynomials of inputs ``names`` as rows (value, d1, d2) at the step's start
        (the form :mod:`.unit_odes` takes)."""
        rows = np.zeros((len(names), 3))
        for i, name in enumerate(names):
            rows[i, 0] = self.u[name]
            d = self.du.get(name)
            if d is not None:
                rows[i, 1], rows[i, 2] = d
        return rows

    def set_inputs(self, values: Mapping[str, float]) -> None:
        for name, value in values.items():
            self.set_input(name, value)

    def get_outputs(self) -> dict[str, float]:
        """Output values at the current time for the current inputs; :class:`OutputError`
        (naming the unit and the time) where the model has none."""
        try:
            return self._outputs()
        except (ValueError, ArithmeticError) as exc:
            raise OutputError(f"{self.name}: no outputs at t = {self.time:.9g} s: {exc}") from exc

    def do_step(self, t: float, h: float) -> None:
        """Advance from ``t`` to ``t + h``; on failure restore the state and raise StepError."""
        if not (math.isfinite(t) and math.isfinite(h)) or h < 0.0:
            raise StepError(f"{self.name}: invalid step t = {t!r}, h = {h!r}")
        bad_input = _first_nonfinite(self.u)
        if bad_input is not None:
            value = self.u[bad_input]
            raise StepError(f"{self.name}: input {bad_input} = {value!r} is not finite at t = {t}")
        saved = self.get_state()
        try:
            self.time = t
            self._advance(t, h)
            bad = _first_nonfinite(self.state)
            if bad is not None:
                raise StepError(f"{self.name}: state {bad} is not finite after the step")
        except Exception as exc:
            self.set_state(saved)
            if isinstance(exc, StepError):
                raise
            raise StepError(
                f"{self.name}: step from t = {t} to {t + h} failed: {type(exc).__name__}: {exc}"
            ) from exc
        self.time = t + h

    def get_state(self) -> dict[str, Any]:
        """A deep copy of everything the unit's future depends on."""
        return {
            "time": self.time,
            "u": dict(self.u),
            "du": {k: list(v) for k, v in self.du.items()},
            "state": {
                k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self.state.items()
            },
        }

    def set_state(self, snapshot: Mapping[str, Any]) -> None:
        """Restore a snapshot from :meth:`get_state` (it stays usable for further restores)."""
        try:
            self.time = float(snapshot["time"])
            self.u = dict(snapshot["u"])
            self.du = {k: (float(v[0]), float(v[1])) for k, v in snapshot.get("du", {}).items()}
            self.state = {
                k: (np.array(v, dtype=float) if isinstance(v, np.ndarray | list) else v)
                for k, v in snapshot["state"].items()
            }
        except (KeyError, TypeError) as exc:
            raise ValueError(f"{self.name}: not a state snapshot of this unit ({exc})") from exc

    @staticmethod
    def state_to_bytes(snapshot: Mapping[str, Any]) -> bytes:
        """Serialise a snapshot; floats keep every bit (shortest round-trip repr), arrays
        their shape (an empty history of shape (0, 6) included)."""

        def encode(value: Any) -> Any:
            if isinstance(value, np.ndarray):
                return {"__array__": value.tolist(), "shape": list(value.shape)}
            if isinstance(value, dict):
                return {k: encode(v) for k, v in value.items()}
            if isinstance(value, np.floating | np.integer):
                return value.item()
            return value

        return json.dumps(encode(dict(snapshot)), allow_nan=True).encode("utf-8")

    @staticmethod
    def state_from_bytes(data: bytes) -> dict[str, Any]:
        def decode(value: Any) -> Any:
            if isinstance(value, dict):
                if "__array__" in value and set(value) <= {"__array__", "shape"}:
                    array = np.array(value["__array__"], dtype=float)
                    return array.reshape(value["shape"]) if "shape" in value else array
                return {k: decode(v) for k, v in value.items()}
            return value

        try:
            return decode(json.loads(data.decode("utf-8")))
        except (UnicodeDecodeError, json.JSONDecodeError, ValueError, TypeError) as exc:
            raise ValueError(f"not a serialised unit state: {exc}") from exc


def _first_nonfinite(values: Mapping[str, Any]) -> str | None:
    """The first key whose value (a number or an array) is not finite, or None."""
    for key, value in values.items():
        if isinstance(value, np.ndarray):
            # a sum is finite when every term is; an overflow falls to the exact check
            if not math.isfinite(value.sum()) and not np.all(np.isfinite(value)):
                return key
        elif not math.isfinite(value):
            return key
    return None
