"""The ``[sim]`` table of a scenario: its settings, defaults and checks."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from rubcosim.reference.assemble import DEFAULT_CHATTER_TOL
from rubcosim.reference.simulate import ENGINES, MIN_RTOL

from .errors import ScenarioError

SIM_DEFAULTS: dict[str, Any] = {
    "t_start": 0.0,
    "t_end": None,
    "output_step": None,
    "engine": "fast",
    "rtol": 1e-10,
    "atol": None,
    "max_events": 100_000,
    "chatter_tol": DEFAULT_CHATTER_TOL,
    "poincare_discard": 0.0,
    "poincare_phase": 0.0,
}
MAX_EVENTS_LIMIT = 10_000_000
MAX_OUTPUT_POINTS = 10_000_000


def sim_settings(raw: Mapping[str, Any]) -> dict[str, Any]:
    """The settings of ``[sim]`` with their defaults; t in s.  A bad one raises
    :class:`ScenarioError` naming it."""
    unknown = sorted(set(raw) - set(SIM_DEFAULTS))
    if unknown:
        raise ScenarioError(f"sim.{unknown[0]} is not a setting (known: {', '.join(SIM_DEFAULTS)})")
    sim = dict(SIM_DEFAULTS)
    sim.update(raw)
    if sim["t_end"] is None:
        raise ScenarioError("sim.t_end is required")
    for key in ("t_start", "t_end", "rtol", "chatter_tol", "poincare_discard", "poincare_phase"):
        sim[key] = _number(f"sim.{key}", sim[key])
    for key in ("output_step", "atol"):
        if sim[key] is not None:
            sim[key] = _number(f"sim.{key}", sim[key])
            if sim[key] <= 0.0:
                raise ScenarioError(f"sim.{key} = {sim[key]!r} must be > 0")
    if sim["t_end"] <= sim["t_start"]:
        raise ScenarioError(
            f"sim.t_end = {sim['t_end']!r} must be greater than sim.t_start = {sim['t_start']!r}"
        )
    if not MIN_RTOL <= sim["rtol"] < 1.0:
        raise ScenarioError(f"sim.rtol = {sim['rtol']!r} is outside [{MIN_RTOL:.3g}, 1)")
    if not 0.0 < sim["chatter_tol"] < 1.0:
        raise ScenarioError(f"sim.chatter_tol = {sim['chatter_tol']!r} is outside (0, 1)")
    if not isinstance(sim["engine"], str) or sim["engine"] not in ENGINES:
        raise ScenarioError(f"sim.engine = {sim['engine']!r} is not one of {', '.join(ENGINES)}")
    me = sim["max_events"]
    if isinstance(me, bool) or not isinstance(me, int) or not 1 <= me <= MAX_EVENTS_LIMIT:
        raise ScenarioError(
            f"sim.max_events = {me!r} must be an integer in [1, {MAX_EVENTS_LIMIT}]"
        )
    step = sim["output_step"] or (sim["t_end"] - sim["t_start"]) / 1000.0
    if (sim["t_end"] - sim["t_start"]) / step > MAX_OUTPUT_POINTS:
        raise ScenarioError(
            f"sim.output_step = {step!r} over sim.t_start = {sim['t_start']!r} to sim.t_end = "
            f"{sim['t_end']!r} gives more than {MAX_OUTPUT_POINTS} output points"
        )
    if sim["output_step"] is None:
        sim["output_step"] = step
    if sim["atol"] is None:
        sim["atol"] = sim["rtol"]
    if sim["poincare_discard"] < 0.0:
        raise ScenarioError("sim.poincare_discard must be >= 0")
    return sim


def _number(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ScenarioError(f"{key} = {value!r} is not a finite number")
    return float(value)
