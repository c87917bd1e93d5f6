"""Continuation of a scenario's periodic orbit, from its settings to its branch: where
the branch starts, the parameter's checks, the progress bar."""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from rubcosim.scenario import Scenario, ScenarioError

from .branch_switching import cascade
from .continuation import Branch, Continuation
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
    doublings: int = 0,
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
    if not (isinstance(doublings, int) and doublings >= 0):
        raise AnalysisError(f"--doublings {doublings!r}: must be an integer >= 0")
    if y0 is not None:
        y = as_state(problem, y0)
    else:
        if not (isinstance(settle, int) and settle >= 1):
            raise AnalysisError(f"--settle {settle!r}: must be an integer >= 1")
        y, problem.mode = settled_start(problem, mu0, settle)
    cont = Continuation(
        problem, mu0, mu1, step=step, max_step=max_step, min_step=min_step,
        max_points=max_points,
    )  # fmt: skip
    bar = _bar(progress, max_points * (1 + doublings), param)
    tick = None if bar is None else _ticker(bar, param)
    try:
        branch = cont.run(y, tick)
        if doublings:
            branch.cascade = cascade(cont, branch, doublings, tick)
    finally:
        if bar is not None:
            bar.close()
    for b in branch.cascade.branches if branch.cascade else [branch]:
        fill_section_points(b, problem.scenario, problem.rtol, problem.mode)
    return branch


def fill_section_points(branch: Branch, scenario: Scenario, rtol: float, mode: int) -> None:
    """Every point's n states on the section (:meth:`OrbitProblem.section_orbit`)."""
    problem = OrbitProblem(scenario, branch.param, branch.period, rtol=rtol, mode=mode)
    branch.section_points = [problem.section_orbit(p.state, p.param) for p in branch.points]


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
