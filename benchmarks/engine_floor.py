"""The engine benchmark's floor (``bench_engines.py``): the cost of one compiled
right-hand-side call (the model's C function, called through its pointer as the engine
calls it), in a loop of independent calls and in one where each call waits
for the one before, taken in rounds paired with ``fast``'s runs; the same distance with
the obstacle out of reach; and what a ``simulate`` call costs besides its steps."""

from __future__ import annotations

import dataclasses
import statistics
import time
from typing import Any

import numba as nb
import numpy as np
from engine_cases import MAX_EVENTS, Case, run_once, settle

from rubcosim.reference import System, simulate
from rubcosim.reference.history import full_rhs
from rubcosim.reference.specialize import compiled_model
from rubcosim.reference.system import N_DELAYED
from rubcosim.reference.unowned import keep_alive, unowned


@nb.njit
def _rhs_calls(y, p, ip, period, calls):  # pragma: no cover - compiled
    """``calls`` right-hand sides of the free motion at times spread over one period
    (so the forcing's cos is not the same call each time); returns a checksum.  The
    arrays are passed as the engine passes its own (views that are not reference-
    counted, :mod:`rubcosim.reference.unowned`): what is timed is the right-hand side,
    not numba's reference counting of the arguments."""
    owners = (y.copy(), np.empty_like(y), np.empty(N_DELAYED))
    y, dy, yd = unowned(owners[0]), unowned(owners[1]), unowned(owners[2])
    acc = 0.0
    for k in range(calls):
        full_rhs(period * k / calls, y, 0, p, ip, None, yd, dy)
        acc += dy[-1]
    keep_alive(owners)
    return acc


@nb.njit
def _chained_rhs_calls(y0, p, ip, period, calls):  # pragma: no cover - compiled
    """:func:`_rhs_calls` with each call's state depending on the previous call's result
    (``y0 + 1e-9 * f``), as a Runge-Kutta stage depends on the stages before it: the
    processor cannot overlap one call with the next (the forcing's ``cos`` included)."""
    owners = (y0.copy(), y0.copy(), np.empty_like(y0), np.empty(N_DELAYED))
    y0, y, dy, yd = unowned(owners[0]), unowned(owners[1]), unowned(owners[2]), unowned(owners[3])
    for k in range(calls):
        full_rhs(period * k / calls, y, 0, p, ip, None, yd, dy)
        for i in range(y.shape[0]):
            y[i] = y0[i] + 1e-9 * dy[i]
    last = y[-1]
    keep_alive(owners)
    return last


def _floor_args(system: System, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The floor loops' arguments: the state on the attractor, the parameters and the
    model tuple (:func:`rubcosim.reference.specialize.compiled_model`)."""
    p = np.array(system.p, dtype=float)
    return np.ascontiguousarray(state, dtype=float), p, compiled_model(system)


def _spread(values: list[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def floor_rounds(
    case: Case, system: System, state: np.ndarray, t_eval: np.ndarray, rtol: float, rounds: int
) -> dict[str, Any]:
    """``fast``'s distance to its floor, in ``rounds`` rounds of one ``fast`` run followed
    at once by a loop of as many right-hand-side calls as it made, and by a loop of as
    many chained calls (:func:`_chained_rhs_calls`): each round's ratio is taken within
    a millisecond or two, so the machine's drift between the two measurements cancels.
    Costs in s per call; ratios: the run's wall time over its calls times the cost."""
    y, p, ip = _floor_args(system, state)
    period = system.forcing_period
    _rhs_calls(y, p, ip, period, 10)  # compile
    _chained_rhs_calls(y, p, ip, period, 10)
    run_once("fast", case, system, t_eval, rtol)  # warm
    cost, chained, ratio, chained_ratio = [], [], [], []
    for _ in range(rounds):
        run = run_once("fast", case, system, t_eval, rtol)
        calls = run.rhs_evaluations
        t0 = time.perf_counter()
        _rhs_calls(y, p, ip, period, calls)
        t1 = time.perf_counter()
        _chained_rhs_calls(y, p, ip, period, calls)
        t2 = time.perf_counter()
        cost.append((t1 - t0) / calls)
        chained.append((t2 - t1) / calls)
        ratio.append(run.wall_s / (t1 - t0))
        chained_ratio.append(run.wall_s / (t2 - t1))
    return {
        "rounds": rounds,
        "rhs_call_s": _spread(cost),
        "rhs_chained_call_s": _spread(chained),
        "fast_over_floor": _spread(ratio),
        "fast_over_chained_floor": _spread(chained_ratio),
    }


def free_flight(case: Case, periods: int, rtol: float, rounds: int) -> dict[str, Any]:
    """``fast``'s distance to its floor on the same model with the obstacle out of reach
    (``case.out_of_reach``), settled on its attractor, at the impacting case's rtol:
    what the step loop costs without an event, so the impacting case's distance splits
    into the step loop and its events."""
    params = {
        role: {**given, **case.out_of_reach.get(role, {})} for role, given in case.params.items()
    }
    free = dataclasses.replace(case, name=f"{case.name} (free flight)", params=params)
    state = settle(free)
    system = free.system(state)
    t_eval = system.forcing_period * np.arange(periods + 1)
    run = run_once("fast", free, system, t_eval, rtol)
    if run.impacts:
        raise RuntimeError(f"{free.name}: {run.impacts} impacts with the obstacle out of reach")
    fl = floor_rounds(free, system, state, t_eval, rtol, rounds)
    return {
        "out_of_reach": case.out_of_reach,
        "rhs_evaluations_per_period": run.rhs_evaluations / periods,
        "rhs_call_s": fl["rhs_call_s"],
        "fast_over_floor": fl["fast_over_floor"],
    }


def call_cost(system: System, rtol: float, repeats: int) -> dict[str, float]:
    """Wall time of a ``fast`` ``simulate`` call over 1e-6 of a forcing period (one step):
    what a call costs besides its steps (the checks, the output and event arrays, the
    call into the compiled engine, the result), s; median and range of ``repeats``
    loops of 1000 calls."""
    t_end = 1e-6 * system.forcing_period
    t_eval = np.array([0.0, t_end])

    def call() -> None:
        simulate(system, t_end, t_eval=t_eval, engine="fast", rtol=rtol, max_events=MAX_EVENTS)

    call()
    costs = []
    for _ in range(max(5, repeats)):
        t0 = time.perf_counter()
        for _ in range(1000):
            call()
        costs.append((time.perf_counter() - t0) / 1000)
    return _spread(costs)
