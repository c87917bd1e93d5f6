"""Lyapunov spectra and monodromy matrices from the variational equations.

The ``fast`` engine carries the tangent matrix through every step and applies the
saltation matrix at every event (:mod:`rubcosim.reference.tangent`), so the
tangent dynamics of a motion with rigid impacts, penalty contact, sliding and
sticking is the system's own, through the same compiled kernels.

Lyapunov spectrum (Benettin's method): k orthonormal tangent vectors are carried
over fixed intervals (the forcing period, or a given time for a system without
forcing) and re-orthonormalised by Gram-Schmidt after each; exponent c is the
mean log growth of column c per unit time, after a transient that is integrated
without the tangent.  Liouville's formula gives the sum of all n exponents
independently of the Gram-Schmidt: the time average of ``tr J`` plus the sum of
``ln|det S|`` over the events, per unit time (``liouville``).

The monodromy matrix of an n-periodic motion is the tangent matrix over n
forcing periods from ``Phi = I`` (:func:`monodromy`; its eigenvalues are the
Floquet multipliers, :mod:`.floquet`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rubcosim.reference.assemble import System
from rubcosim.reference.core import STATUS_MESSAGES, STATUS_OK
from rubcosim.reference.tangent import FD_REL, T_LOGDET, T_TRACE

from .errors import AnalysisError, MapError
from .maps import DEFAULT_MAX_EVENTS, model_of

LYAPUNOV_RTOL = 1e-10
DEFAULT_PERIODS = 1000
DEFAULT_TRANSIENT = 200


@dataclass(frozen=True)
class Lyapunov:
    """A Lyapunov spectrum: ``exponents`` (1/s, largest first) over ``intervals``
    intervals of ``interval`` s after ``transient`` intervals; ``half`` the same from
    the first half of the intervals only (the difference shows the convergence);
    ``liouville`` (1/s) the sum of all exponents by Liouville's formula, ``trace``
    (1/s) its smooth part (mean ``tr J``) and ``jumps`` (1/s) its event part (``sum
    ln|det S|`` per unit time); ``impacts`` the impacts and contact onsets counted."""

    exponents: np.ndarray
    half: np.ndarray
    interval: float
    intervals: int
    transient: int
    liouville: float
    trace: float
    jumps: float
    impacts: int
    state: np.ndarray
    mode: int

    @property
    def per_interval(self) -> np.ndarray:
        """The exponents per interval (per forcing period when that is the interval)."""
        return self.exponents * self.interval

    @property
    def largest(self) -> float:
        return float(self.exponents[0])


def _check_system(system: System) -> None:
    if system.has_delay:
        raise AnalysisError(
            "units.controller: a delayed-feedback system has an infinite-dimensional state "
            "(its history); the variational equations (Lyapunov exponents, variational "
            "Floquet multipliers) take delay-free systems only; `rubcosim lyapunov "
            "--uncontrolled` (rc.lyapunov(..., uncontrolled=True)) takes the scenario "
            "without its controller"
        )


def _kernels(system: System) -> Any:
    """The compiled variational loops (:mod:`.tangent_kernels`): one module for every model."""
    from . import tangent_kernels  # compiled on first use (numba's cache after that)

    return tangent_kernels


def _args(system: System, rtol: float, t_scale: float) -> tuple[Any, ...]:
    """``p``, the model tuple, the tolerances, difference steps: as the stroboscopic map."""
    if not (isinstance(rtol, float | int) and 1e-14 <= rtol < 1.0):
        raise AnalysisError(f"--rtol {rtol!r}: must be in [1e-14, 1)")
    scale = np.asarray(system.state_scale, dtype=float)
    p, model = model_of(system)
    tol = (float(rtol), np.ascontiguousarray(rtol * scale), math.inf)
    return p, model, tol, np.ascontiguousarray(FD_REL * scale), FD_REL * t_scale


def monodromy(
    system: System,
    y: np.ndarray,
    periods: int,
    mode: int,
    rtol: float,
    max_events: int = DEFAULT_MAX_EVENTS,
) -> tuple[np.ndarray, int, np.ndarray, int]:
    """The tangent matrix over ``periods`` forcing periods from ``(0, y, mode)`` with
    ``Phi(0) = I``: ``(Phi, impacts, final state, final mode)``; raises
    :class:`MapError` when the engine fails."""
    _check_system(system)
    T = system.forcing_period
    p, model, tol, fd, t_fd = _args(system, rtol, T / (2.0 * math.pi))
    yy = np.array(y, dtype=float)
    Phi = np.eye(yy.size)
    stats = np.zeros(3)
    st, done, m_end, impacts = _kernels(system).tangent_periods(
        yy, int(mode), 0.0, T, periods, p, model, tol, max_events, Phi, fd, t_fd, stats
    )
    if st != STATUS_OK:
        raise MapError(f"the variational run failed: {STATUS_MESSAGES[st]} (period {done + 1})")
    return Phi, int(impacts), yy, int(m_end)


def lyapunov_spectrum(
    system: System,
    periods: int = DEFAULT_PERIODS,
    transient: int = DEFAULT_TRANSIENT,
    *,
    rtol: float = LYAPUNOV_RTOL,
    y0: np.ndarray | None = None,
    mode: int | None = None,
    count: int | None = None,
    interval: float | None = None,
    max_events: int = DEFAULT_MAX_EVENTS,
) -> Lyapunov:
    """The ``count`` (default all) largest Lyapunov exponents of the motion from ``y0``
    (default the system's initial state) at t = 0: ``transient`` intervals discarded,
    then ``periods`` intervals measured.  The interval is the forcing period, or
    ``interval`` (s) for a system without forcing."""
    _check_system(system)
    n = system.n_state
    if not (isinstance(periods, int) and periods >= 1):
        raise AnalysisError(f"--periods {periods!r}: must be an integer >= 1")
    if not (isinstance(transient, int) and transient >= 0):
        raise AnalysisError(f"--transient {transient!r}: must be an integer >= 0")
    count = n if count is None else count
    if not (isinstance(count, int) and 1 <= count <= n):
        raise AnalysisError(f"count = {count!r}: must be an integer in [1, {n}]")
    T = system.forcing_period if interval is None else interval
    if not (isinstance(T, float | int) and math.isfinite(T) and T > 0.0):
        what = "the system has no forcing period: give" if interval is None else "must be >"
        raise AnalysisError(f"interval = {interval!r}: {what} a time interval > 0 (s)")
    y = np.array(system.y0 if y0 is None else y0, dtype=float)
    if y.shape != (n,) or not np.all(np.isfinite(y)):
        raise AnalysisError(f"y0 must be {n} finite numbers")
    m = system.mode0 if mode is None else int(mode)
    p, model, tol, fd, t_fd = _args(system, rtol, T / (2.0 * math.pi))
    Q = np.ascontiguousarray(np.eye(n)[:, :count])
    logs = np.zeros((periods, count))
    stats = np.zeros(3)
    st, done, m_end, impacts = _kernels(system).lyapunov_run(
        y, m, 0.0, float(T), transient, periods, p, model, tol, max_events, Q, fd, t_fd, logs, stats
    )
    if st != STATUS_OK:
        where = f"measured interval {done + 1}" if done or st else "the transient"
        raise AnalysisError(f"the run failed in {where}: {STATUS_MESSAGES[st]}")
    span = periods * T
    half = max(1, periods // 2)
    order = np.argsort(-logs.sum(axis=0), kind="stable")
    return Lyapunov(
        exponents=logs.sum(axis=0)[order] / span,
        half=logs[:half].sum(axis=0)[order] / (half * T),
        interval=float(T),
        intervals=periods,
        transient=transient,
        liouville=float(stats[T_TRACE] + stats[T_LOGDET]) / span,
        trace=float(stats[T_TRACE]) / span,
        jumps=float(stats[T_LOGDET]) / span,
        impacts=int(impacts),
        state=y,
        mode=int(m_end),
    )


def lyapunov_report(lyap: Lyapunov) -> dict[str, Any]:
    """JSON-able summary (``-inf`` as the string "-inf")."""

    def num(v: float) -> float | str:
        return float(v) if math.isfinite(v) else str(v)

    return {
        "exponents_per_unit_time": [num(v) for v in lyap.exponents],
        "exponents_per_interval": [num(v) for v in lyap.per_interval],
        "first_half_per_unit_time": [num(v) for v in lyap.half],
        "sum": num(float(np.sum(lyap.exponents))),
        "liouville_sum": num(lyap.liouville),
        "mean_trace": num(lyap.trace),
        "events_log_det_per_unit_time": num(lyap.jumps),
        "interval_s": lyap.interval,
        "intervals": lyap.intervals,
        "transient_intervals": lyap.transient,
        "impacts_per_interval": lyap.impacts / lyap.intervals,
    }


def sweep_lyapunov(
    scenario: Any, result: Any, periods: int | None = None
) -> dict[str, list[float | None]]:
    """Per direction of a sweep (``SweepResult``) of ``scenario``: the largest Lyapunov
    exponent (1/s) of each value's motion from its last stroboscopic point, over
    ``periods`` (default the sweep's kept periods) forcing periods; None where the
    value failed."""
    from .sweep import sweep_systems

    systems = sweep_systems(scenario, result.param, result.values)
    n_periods = result.periods if periods is None else periods
    out: dict[str, list[float | None]] = {}
    for d, pts in result.points.items():
        row: list[float | None] = []
        for i, system in enumerate(systems):
            if result.status[d][i] != 0 or not np.all(np.isfinite(pts[i, -1])):
                row.append(None)
                continue
            try:
                lyap = lyapunov_spectrum(
                    system, n_periods, 0, y0=pts[i, -1], mode=int(result.modes[d][i, -1]), count=1
                )
                row.append(lyap.largest)
            except AnalysisError:
                row.append(None)
        out[d] = row
    return out
