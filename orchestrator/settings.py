"""Settings of a co-simulation run: the ``[cosim]`` table of a scenario."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

ALGORITHMS = ("gauss-seidel", "jacobi")
EVENT_MODES = ("locate", "step", "off")
KINK_MODES = ("locate", "off")
BACKENDS = ("direct", "fmu")
MASTERS = ("auto", "compiled", "python")
UNIT_INTEGRATORS = ("exact", "dop853")


class SettingsError(ValueError):
    """A ``[cosim]`` value is invalid; the message names ``cosim.key``."""


# rebounds slower than this (relative to the velocity scale) the master cannot resolve
MIN_CHATTER_TOL = 1e-7


@dataclass(frozen=True)
class CosimSettings:
    """How the master couples the units.

    Times are in seconds; ``None`` steps are derived from the forcing period
    ``T``: initial/fixed step ``T/400``, ``max_step = T/10``, ``min_step = 1e-9 T``.
    """

    backend: str = "direct"  # "direct" (in-process units) or "fmu" (FMUs through fmpy)
    fmu_units: tuple[str, ...] = ()  # units run as FMUs whatever the backend (mixed runs)
    # "compiled": the numba loop (in-process rotors, stators and bearings only); "python":
    # the Python master (any unit, FMUs included); "auto": compiled where it can
    master: str = "auto"
    isolate: bool = False  # every FMU in a worker process: a crash fails the run, not ours
    algorithm: str = "gauss-seidel"  # or "jacobi"
    extrapolation: int = 2  # polynomial order of the coupled inputs over a step: 0, 1, 2
    adaptive: bool = True  # macro step from the coupling error estimate (PI control)
    step: float | None = None  # fixed step, or the first step when adaptive
    min_step: float | None = None
    max_step: float | None = None
    rtol: float = 1e-7  # coupling error tolerance, relative to each signal's magnitude
    iterations: int = 1  # > 1: fixed-point iteration of every step, at most this many passes
    iteration_tol: float = 1e-10  # relative change of the coupled inputs that ends iterating
    events: str = "locate"  # "locate": roll back and step onto events; "step": at the next
    # communication point; "off": no event handling at all (plain master)
    event_tol: float = 1e-10  # event time tolerance, relative to the forcing period
    # "locate": kinks and jumps in a foreign FMU's outputs are located like events and
    # restart the extrapolation (orchestrator.kink_steps); "off": left to error control
    kinks: str = "locate"
    # rebound speed (relative to the velocity scale) ending chatter; None: the scenario's
    # sim.chatter_tol, raised to MIN_CHATTER_TOL (the one rule of both sides)
    chatter_tol: float | None = None
    max_events_per_period: int = 2000
    # how linear units (the rotors) step: "exact" (matrix exponential) or "dop853"
    unit_integrator: str = "exact"
    unit_rtol: float = 1e-10  # tolerances of the units' own integrators
    unit_atol: float = 1e-14
    order: tuple[str, ...] = ()  # Gauss-Seidel order of the units (default: by dependency)

    def with_chatter_tol(self, sim_chatter_tol: float) -> CosimSettings:
        """The threshold that ends chattering, from the scenario's ``sim.chatter_tol`` when
        not set here: the reference's rule, at the finest the master can resolve."""
        if self.chatter_tol is not None:
            return self
        return replace(self, chatter_tol=max(sim_chatter_tol, MIN_CHATTER_TOL))

    def with_defaults(self, period: float) -> CosimSettings:
        step = self.step or period / 400.0
        return replace(
            self,
            chatter_tol=MIN_CHATTER_TOL if self.chatter_tol is None else self.chatter_tol,
            step=step,
            max_step=self.max_step or max(period / 10.0, step),
            min_step=self.min_step or min(1e-9 * period, step),
        )


def _number(key: str, value: Any, low: float, high: float = math.inf, open_low=True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SettingsError(f"cosim.{key} = {value!r} is not a finite number")
    if value < low or (open_low and value == low) or value > high:
        bound = f"> {low:g}" if open_low else f">= {low:g}"
        raise SettingsError(f"cosim.{key} = {value!r} must be {bound} and <= {high:g}")
    return float(value)


def _integer(key: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SettingsError(f"cosim.{key} = {value!r} must be an integer in [{low}, {high}]")
    return value


def _choice(key: str, value: Any, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise SettingsError(f"cosim.{key} = {value!r} is not one of {', '.join(choices)}")
    return value


def cosim_settings(raw: Mapping[str, Any]) -> CosimSettings:
    """Validate a ``[cosim]`` table (unknown keys and bad values name the key)."""
    known = {f.name for f in fields(CosimSettings)}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise SettingsError(
            f"cosim.{unknown[0]} is not a setting (known: {', '.join(sorted(known))})"
        )
    v: dict[str, Any] = {}
    for key, value in raw.items():
        if key == "backend":
            v[key] = _choice(key, value, BACKENDS)
        elif key == "master":
            v[key] = _choice(key, value, MASTERS)
        elif key == "algorithm":
            v[key] = _choice(key, value, ALGORITHMS)
        elif key == "events":
            v[key] = _choice(key, value, EVENT_MODES)
        elif key == "kinks":
            v[key] = _choice(key, value, KINK_MODES)
        elif key == "unit_integrator":
            v[key] = _choice(key, value, UNIT_INTEGRATORS)
        elif key == "extrapolation":
            v[key] = _integer(key, value, 0, 2)
        elif key == "iterations":
            v[key] = _integer(key, value, 1, 100)
        elif key == "max_events_per_period":
            v[key] = _integer(key, value, 1, 10**7)
        elif key in ("adaptive", "isolate"):
            if not isinstance(value, bool):
                raise SettingsError(f"cosim.{key} = {value!r} must be true or false")
            v[key] = value
        elif key in ("order", "fmu_units"):
            if not isinstance(value, list) or not all(isinstance(s, str) for s in value):
                raise SettingsError(f"cosim.{key} must be a list of unit names")
            if len(set(value)) != len(value):
                raise SettingsError(f"cosim.{key} = {value!r} names a unit twice")
            v[key] = tuple(value)
        elif key in ("rtol", "iteration_tol", "event_tol", "chatter_tol", "unit_rtol"):
            v[key] = _number(key, value, 0.0, 1.0)
        elif key == "unit_atol":
            v[key] = _number(key, value, 0.0, open_low=False)
        else:  # step, min_step, max_step
            v[key] = _number(key, value, 0.0)
    settings = CosimSettings(**v)
    if settings.chatter_tol is not None and settings.chatter_tol < MIN_CHATTER_TOL:
        # slower rebounds bounce less than a few ulps of the gap: the locator cannot see them
        raise SettingsError(
            f"cosim.chatter_tol = {settings.chatter_tol!r} must be >= 1e-7 (slower rebounds "
            "are below what the gap resolves in double precision)"
        )
    if settings.unit_rtol < 1e-13:
        raise SettingsError(f"cosim.unit_rtol = {settings.unit_rtol!r} must be >= 1e-13")
    if settings.min_step and settings.max_step and settings.min_step > settings.max_step:
        raise SettingsError("cosim.min_step must not exceed cosim.max_step")
    return settings
