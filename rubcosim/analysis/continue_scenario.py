"""Continuation of a scenario's periodic orbit, from its settings to its branch: where
the branch starts, the parameter's checks, the progress bar."""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from rubcosim.scenario import Scenario, ScenarioError

from .continuation import Branch, continue_orbit
from .errors import AnalysisError
from .floquet import FLOQUET_RTOL
from .orbit_problem import OrbitProblem, as_state, settled_start

DEFAULT_SETTLE = 300  # forcing periods from the initial state before Newton


def run_continuation(
    scenario: Scenario,
    param: str,
    start: float | None,
    stop: float,
    *,
    period: int = 1,
    y0: Any = None,
    settle: int = DEFAULT_SETTLE,
    rtol: float | None = None,
    step: float = 0.02,
    max_step: float = 0.05,
    min_step: float = 1e-7,
    max_points: int = 500,
    progress: bool = False,
) -> Branch:
    """See :func:`rubcosim.api.continuation`."""
    problem = OrbitProblem(scenario, param, period, rtol=FLOQUET_RTOL if rtol is None else rtol)
    mu0 = problem.value() if start is None else _number("--from", start)
    mu1 = _number("--to", stop)
    for flag, value in (("--from", mu0), ("--to", mu1)):
        try:
            problem.system(value)
        except ScenarioError as exc:
            raise ScenarioError(f"{flag} {value:g}: {exc}") from None
    if mu0 == mu1:
        raise AnalysisError(f"--from and --to: both {mu0:g}; the range must not be empty")
    problem.mu_scale = abs(mu1 - mu0)
    if y0 is not None:
        y = as_state(problem, y0)
    else:
        if not (isinstance(settle, int) and settle >= 1):
            raise AnalysisError(f"--settle {settle!r}: must be an integer >= 1")
        y = settled_start(problem, mu0, settle)
    bar = _bar(progress, max_points, param)
    try:
        return continue_orbit(
            problem,
            y,
            mu0,
            mu1,
            progress=None if bar is None else _ticker(bar, param),
            step=step,
            max_step=max_step,
            min_step=min_step,
            max_points=max_points,
        )
    finally:
        if bar is not None:
            bar.close()


def _number(flag: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise AnalysisError(f"{flag} {value!r}: not a number") from None
    if not math.isfinite(v):
        raise AnalysisError(f"{flag} {value!r}: not a finite number")
    return v


def _bar(enabled: bool, total: int, param: str) -> Any:
    """A tqdm bar of the points on a terminal's stderr, else None."""
    if not enabled or not getattr(sys.stderr, "isatty", lambda: False)():
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=f"continuation in {param}", leave=False, delay=1.0,
                file=sys.stderr, unit=" points")  # fmt: skip


def _ticker(bar: Any, param: str) -> Any:
    def tick(mu: float) -> None:
        bar.set_description_str(f"continuation: {param} = {mu:.6g}", refresh=False)
        bar.update(1)

    return tick


def settings_of(branch: Branch, **given: Any) -> dict[str, Any]:
    """The settings a report states: what was asked, JSON-able."""
    out = {}
    for k, v in given.items():
        out[k] = v.tolist() if isinstance(v, np.ndarray) else v
    out["period"] = branch.period
    return out
