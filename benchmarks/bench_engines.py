"""Engine benchmark: wall time per forcing period at equal accuracy.

Measures three integrators of the same nonsmooth models:

* ``fast``: the numba-compiled event-driven DOP853 engine (``simulate(engine="fast")``);
* ``accurate``: the scipy DOP853 stepper driven by the shared event machinery
  (``simulate(engine="accurate")``);
* ``scipy loop``: what a typical user would write, a ``scipy.integrate.solve_ivp``
  (DOP853) call with a terminal event on the gap (``gap = 0``, direction -1),
  restarted after every event with the impact map applied; its right-hand side is a
  Python function that calls the component kernels (``jeffcott_force``,
  ``free_acceleration``) and its impact map calls ``rigid_impact`` /
  ``impact_velocity``.  It has no notion of sustained contact or sticking, so the
  cases below are chosen so that the motion keeps impacting and never settles.

Cases (both start on their attractor, a stable period-1 impacting orbit, found by a
settling run from rest, so every period costs the same and integration errors do not
grow):

* ``rotor``: the flagship Jeffcott rotor (z = 0.05, e/d = 0.5, speed ratio 1.2) on a
  rigid stator offset by 0.8 clearances along x, restitution 0.8, friction 0.05:
  three impacts per period, no sliding or sticking.
* ``duffing``: the impact Duffing oscillator x'' + 0.1 x' + x + x^3 = cos(1.2 t) with a
  rigid one-sided barrier at x = 0.3, restitution 0.8: one impact per period.

Equal accuracy: the trusted reference is ``simulate(engine="accurate", rtol=1e-12)``.
The error of a run is the largest deviation of its positions from the reference on a
stroboscopic grid (t = k T, k = 0..periods), each position normalised by the largest
absolute value of its reference output.  For each integrator rtol is scanned from 1e-6
to 1e-12 in half decades (atol = rtol times the state scale of the system: clearance
for displacements, clearance times frequency for velocities, the engines' own
convention); the loosest rtol is kept whose error is <= the target (1e-8) and whose next
tighter rtol passes too (so that a lucky cancellation is not picked).

Timing: at that rtol, one warm-up run (numba compilation excluded), then the median of
at least ``--repeats`` runs (more for runs that take milliseconds, up to ~0.3 s of
runs).  The wall time covers the whole call (``simulate(...)`` or the scipy loop).

The floor of ``fast`` (issue: "within 2x of its right-hand-side floor"): its
right-hand-side calls per period times the cost of one compiled call, measured in a
compiled loop of calls spread over a forcing period; the ratio of ``fast``'s time to
that floor is what its step control, event location and bookkeeping add.  The ratio
is taken in rounds (``--floor-rounds``): one ``fast`` run, then at once a loop of as
many calls as that run made; its figure is the median of the rounds' ratios, so this
machine's drift over the seconds between the timed runs and the loops cancels.  The
calls of that loop are independent, so the processor overlaps them (the forcing's
``cos`` of one call with the arithmetic of the next); the stages of a step cannot
overlap, each waiting for the ones before.  So a second floor is printed beside it,
from a loop of calls that each wait for the one before (in the same rounds); the
target stays judged on the first.  Last, the same distance on the same model with the
obstacle out of reach (``Case.out_of_reach``: settled there, at the impacting run's
rtol): the step loop alone, so that the impacting case's distance splits into the step
loop and what its events add.

Run from the repository root::

    .venv/bin/python benchmarks/bench_engines.py
    .venv/bin/python benchmarks/bench_engines.py --periods 50 --repeats 5 --out /tmp/e.json

It writes a JSON file (``--out``, default ``benchmarks/results/engines.json``) and a
Markdown table (``--md``, default ``benchmarks/results/engines.md``), and prints the
table.  It takes well under a minute (about 15 s on two idle cores; the settling and
reference runs and the rtol scans are included).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np
from scipy.integrate import solve_ivp
from stamp import stamp

from rubcosim.components.oscillator import free_acceleration, impact_velocity
from rubcosim.components.rotor import jeffcott_force
from rubcosim.components.stator import contact_geometry, rigid_impact
from rubcosim.reference import System, build_system, make_unit, simulate
from rubcosim.reference.history import full_rhs
from rubcosim.reference.system import N_DELAYED
from rubcosim.reference.unowned import keep_alive, unowned

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results" / "engines.json"
DEFAULT_MD = REPO / "benchmarks" / "results" / "engines.md"

REFERENCE_RTOL = 1e-12
# rtol scan, loosest first: 1e-6, 3.16e-7, 1e-7, ..., 1e-12 (half decades).
RTOL_SCAN = tuple(10.0 ** (-e / 2.0) for e in range(12, 25))
INTEGRATORS = ("fast", "accurate", "scipy_loop")
LABELS = {"fast": "`fast`", "accurate": "`accurate`", "scipy_loop": "scipy `solve_ivp` loop"}
MAX_EVENTS = 100_000
MIN_TIMED_S = 0.3  # keep repeating quick runs until this much time has been measured
MAX_RUNS = 200


# ---------------------------------------------------------------------------- cases
@dataclass(frozen=True)
class Case:
    """A benchmark model: its units' parameters and its plain scipy counterpart."""

    name: str
    description: str
    params: dict[str, dict[str, Any]]  # role -> {"type": ..., parameter: value}
    state_keys: tuple[str, ...]  # (role, parameter) names of the initial state, in order
    positions: tuple[str, ...]  # outputs compared against the reference
    settle_periods: int
    loop: Callable[..., tuple[np.ndarray, int, int]]
    # parameters that put the obstacle out of reach: the same model in free flight
    out_of_reach: dict[str, dict[str, float]]

    def system(self, state: np.ndarray | None = None) -> System:
        """Build the system, optionally starting from ``state`` (same order as its states)."""
        units = {}
        for role, given in self.params.items():
            q = {k: v for k, v in given.items() if k != "type"}
            if state is not None and role == self.state_keys[0].split(".")[0]:
                for key, value in zip(self.state_keys, state, strict=True):
                    q[key.split(".")[1]] = float(value)
            units[role] = make_unit(role, given["type"], q)
        return build_system(units)


def rotor_loop(
    case: Case, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray
) -> tuple[np.ndarray, int, int]:
    """Plain solve_ivp event loop for the Jeffcott rotor on a rigid stator.

    Returns the positions (x, y) at ``t_eval``, the number of impacts and of rhs calls.
    """
    r = case.params["rotor"]
    s = case.params["stator"]
    m, c, k, e, w = r["mass"], r["damping"], r["stiffness"], r["eccentricity"], r["speed"]
    rd = r["disc_radius"]
    d, xs, ys, rest, mu = (
        s["clearance"],
        s["x_offset"],
        s["y_offset"],
        s["restitution"],
        s["friction"],
    )

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        fx, fy = jeffcott_force(t, y[0], y[1], y[2], y[3], m, c, k, e, w, 0.0)
        return np.array([y[2], y[3], fx / m, fy / m])

    def gap(t: float, y: np.ndarray) -> float:
        dist, _, _ = contact_geometry(y[0] - xs, y[1] - ys)
        return d - dist

    gap.terminal = True  # type: ignore[attr-defined]
    gap.direction = -1  # type: ignore[attr-defined]

    def impact(ye: np.ndarray) -> np.ndarray:
        _, nx, ny = contact_geometry(ye[0] - xs, ye[1] - ys)
        vx, vy = rigid_impact(ye[2], ye[3], nx, ny, rest, mu, rd, w)
        return np.array([ye[0], ye[1], vx, vy])

    return _event_loop(rhs, gap, impact, y0, t_eval, rtol, atol, 2)


def duffing_loop(
    case: Case, y0: np.ndarray, t_eval: np.ndarray, rtol: float, atol: np.ndarray
) -> tuple[np.ndarray, int, int]:
    """Plain solve_ivp event loop for the impact Duffing oscillator (one-sided rigid stop).

    Returns the position x at ``t_eval``, the number of impacts and of rhs calls.
    """
    o = case.params["oscillator"]
    a, b, c3 = o["linear_stiffness"], o["damping"], o["cubic_stiffness"]
    f, w, barrier, rest = (
        o["forcing_amplitude"],
        o["forcing_frequency"],
        o["barrier"],
        o["restitution"],
    )

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], free_acceleration(t, y[0], y[1], a, b, c3, f, w)])

    def gap(t: float, y: np.ndarray) -> float:
        return barrier - y[0]

    gap.terminal = True  # type: ignore[attr-defined]
    gap.direction = -1  # type: ignore[attr-defined]

    def impact(ye: np.ndarray) -> np.ndarray:
        return np.array([ye[0], impact_velocity(ye[1], rest)])

    return _event_loop(rhs, gap, impact, y0, t_eval, rtol, atol, 1)


def _event_loop(
    rhs: Callable[[float, np.ndarray], np.ndarray],
    gap: Callable[[float, np.ndarray], float],
    impact: Callable[[np.ndarray], np.ndarray],
    y0: np.ndarray,
    t_eval: np.ndarray,
    rtol: float,
    atol: np.ndarray,
    n_pos: int,
) -> tuple[np.ndarray, int, int]:
    """solve_ivp until the gap closes, apply the impact map, restart; until t_eval[-1]."""
    t_end = float(t_eval[-1])
    t = float(t_eval[0])
    y = np.array(y0, dtype=float)
    out = np.full((t_eval.shape[0], n_pos), np.nan)
    i = 0
    impacts = 0
    nfev = 0
    while True:
        sol = solve_ivp(
            rhs,
            (t, t_end),
            y,
            method="DOP853",
            t_eval=t_eval[i:],
            events=gap,
            rtol=rtol,
            atol=atol,
        )
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed at t = {t:.9g}: {sol.message}")
        nfev += sol.nfev
        n = len(sol.t)  # a list, not an array, when no grid point fell in this stretch
        if n:
            out[i : i + n] = sol.y[:n_pos].T
            i += n
        if sol.status != 1:
            break
        t = float(sol.t_events[0][0])
        y = impact(sol.y_events[0][0])
        impacts += 1
        if impacts > MAX_EVENTS:
            raise RuntimeError("scipy loop: too many impacts")
    return out, impacts, nfev


CASES = (
    Case(
        name="rotor",
        description=(
            "Jeffcott rotor (m = 10 kg, z = 0.05, wn = 316.2 rad/s, e = 5e-5 m, speed ratio 1.2) "
            "on a rigid stator (clearance 1e-4 m) offset by 8e-5 m along x, restitution 0.8, "
            "friction 0.05, disc radius 0.05 m; period-1 orbit with 3 impacts per period"
        ),
        params={
            "rotor": dict(
                type="jeffcott",
                mass=10.0,
                damping=316.227766,
                stiffness=1e6,
                eccentricity=5e-5,
                speed=379.473319,
                disc_radius=0.05,
            ),
            "stator": dict(
                type="rigid",
                clearance=1e-4,
                restitution=0.8,
                friction=0.05,
                x_offset=8e-5,
                y_offset=0.0,
            ),
        },
        state_keys=("rotor.x0", "rotor.y0", "rotor.vx0", "rotor.vy0"),
        positions=("rotor.x", "rotor.y"),
        settle_periods=300,
        loop=rotor_loop,
        out_of_reach={"stator": {"clearance": 1.0, "x_offset": 0.0}},
    ),
    Case(
        name="duffing",
        description=(
            "impact Duffing oscillator x'' + 0.1 x' + x + x^3 = cos(1.2 t), rigid one-sided "
            "barrier at x = 0.3, restitution 0.8; period-1 orbit with 1 impact per period"
        ),
        params={
            "oscillator": dict(
                type="impact_oscillator",
                linear_stiffness=1.0,
                damping=0.1,
                cubic_stiffness=1.0,
                forcing_amplitude=1.0,
                forcing_frequency=1.2,
                barrier=0.3,
                restitution=0.8,
                stop="rigid_one_sided",
            ),
        },
        state_keys=("oscillator.x0", "oscillator.v0"),
        positions=("oscillator.x",),
        settle_periods=200,
        loop=duffing_loop,
        out_of_reach={"oscillator": {"barrier": 10.0}},
    ),
)


# ---------------------------------------------------------------------------- runs
@dataclass
class Run:
    positions: np.ndarray  # (n_eval, n_pos)
    impacts: int
    rhs_evaluations: int
    wall_s: float


def run_once(kind: str, case: Case, system: System, t_eval: np.ndarray, rtol: float) -> Run:
    """One run of integrator ``kind`` on the benchmark grid; wall time of the whole call."""
    if kind == "scipy_loop":
        atol = rtol * system.state_scale
        t0 = time.perf_counter()
        pos, impacts, nfev = case.loop(case, system.y0.copy(), t_eval, rtol, atol)
        wall = time.perf_counter() - t0
        return Run(pos, impacts, nfev, wall)
    t0 = time.perf_counter()
    res = simulate(
        system, float(t_eval[-1]), t_eval=t_eval, engine=kind, rtol=rtol, max_events=MAX_EVENTS
    )
    wall = time.perf_counter() - t0
    if not res.ok:
        raise RuntimeError(f"{kind} at rtol {rtol:g} on {case.name}: {res.message}")
    pos = np.column_stack([res.output(name) for name in case.positions])
    return Run(pos, res.counters["impacts"], res.counters["rhs_evaluations"], wall)


def max_error(pos: np.ndarray, ref: np.ndarray) -> float:
    """Largest deviation, each position normalised by the max |reference| of that position."""
    scale = np.max(np.abs(ref), axis=0)
    err = np.max(np.abs(pos - ref), axis=0) / scale
    return float(np.max(err)) if np.all(np.isfinite(pos)) else math.inf


def settle(case: Case) -> np.ndarray:
    """State on the attractor: run from rest for ``settle_periods`` and take the final state."""
    system = case.system()
    t_end = case.settle_periods * system.forcing_period
    res = simulate(system, t_end, t_eval=np.array([t_end]), engine="accurate", rtol=1e-10)
    if not res.ok or res.final_mode != 0:
        raise RuntimeError(
            f"{case.name}: settling run ended with {res.message}, mode {res.final_mode}"
        )
    return res.final_state.copy()


def check_reference(case: Case, system: System, t_eval: np.ndarray) -> tuple[Run, dict[str, Any]]:
    """The reference run and the checks that make the case fit for the scipy loop."""
    t_end = float(t_eval[-1])
    t0 = time.perf_counter()
    res = simulate(
        system, t_end, t_eval=t_eval, engine="accurate", rtol=REFERENCE_RTOL, max_events=MAX_EVENTS
    )
    wall = time.perf_counter() - t0
    if not res.ok:
        raise RuntimeError(f"{case.name}: reference run failed: {res.message}")
    period = system.forcing_period
    n_periods = int(round(t_end / period))
    impacts = res.events.t[res.events.of_kind("impact")]
    per_period = np.bincount(
        np.minimum((impacts / period).astype(int), n_periods - 1), minlength=n_periods
    )
    other_events = int(res.events.t.shape[0] - impacts.shape[0])
    info = {
        "rtol": REFERENCE_RTOL,
        "final_mode": res.final_mode,
        "impacts": int(impacts.shape[0]),
        "impacts_per_period_min": int(per_period.min()),
        "impacts_per_period_max": int(per_period.max()),
        "non_impact_events": other_events,
        "min_rebound_normal_speed_over_velocity_scale": _min_rebound(case, res, system),
        "wall_s": wall,
    }
    if res.final_mode != 0 or other_events or per_period.min() != per_period.max():
        raise RuntimeError(
            f"{case.name}: the reference does not keep a steady impacting motion: {info}"
        )
    pos = np.column_stack([res.output(name) for name in case.positions])
    return Run(pos, int(impacts.shape[0]), res.counters["rhs_evaluations"], wall), info


def _min_rebound(case: Case, res: Any, system: System) -> float:
    """Smallest normal rebound speed over the velocity scale: how far from chattering."""
    idx = res.events.of_kind("impact")
    if idx.shape[0] == 0:
        return math.nan
    st = res.events.state[idx]
    if "stator" in case.params:
        s = case.params["stator"]
        rx, ry = st[:, 0] - s["x_offset"], st[:, 1] - s["y_offset"]
        speed = -(st[:, 2] * rx + st[:, 3] * ry) / np.hypot(rx, ry)
    else:
        speed = np.abs(st[:, 1])
    return float(speed.min() / system.velocity_scale)


def choose_rtol(
    kind: str, case: Case, system: System, t_eval: np.ndarray, ref: Run, target: float
) -> tuple[float, list[dict[str, Any]]]:
    """Loosest rtol of the scan whose error and the next tighter one's are <= target."""
    scan: list[dict[str, Any]] = []
    run_once(kind, case, system, t_eval, RTOL_SCAN[0])  # warm-up (numba compilation)
    chosen = None
    for i, rtol in enumerate(RTOL_SCAN):
        run = run_once(kind, case, system, t_eval, rtol)
        err = max_error(run.positions, ref.positions)
        scan.append({"rtol": rtol, "error": err, "impacts": run.impacts, "wall_s": run.wall_s})
        ok = err <= target
        if ok and chosen is None:
            chosen = i
        elif not ok:
            chosen = None
        if chosen is not None and (i > chosen or i == len(RTOL_SCAN) - 1):
            return RTOL_SCAN[chosen], scan
    raise RuntimeError(f"{kind} on {case.name}: no rtol in the scan reaches error <= {target:g}")


def time_runs(
    kind: str, case: Case, system: System, t_eval: np.ndarray, rtol: float, repeats: int
) -> tuple[list[float], Run]:
    """Wall times after one warm-up run: at least ``repeats`` runs and ~MIN_TIMED_S of them."""
    last = run_once(kind, case, system, t_eval, rtol)
    walls: list[float] = []
    while len(walls) < repeats or (sum(walls) < MIN_TIMED_S and len(walls) < MAX_RUNS):
        last = run_once(kind, case, system, t_eval, rtol)
        walls.append(last.wall_s)
    return walls, last


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


def _floor_args(system: System, state: np.ndarray) -> tuple[np.ndarray, tuple, tuple]:
    """The floor loops' arguments: the state on the attractor and the parameter tuples."""
    p = tuple(float(v) for v in system.p)
    ip = tuple(int(v) for v in system.ip)
    return np.ascontiguousarray(state, dtype=float), p, ip


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


def bench_case(
    case: Case, periods: int, repeats: int, target: float, rounds: int
) -> dict[str, Any]:
    start = time.perf_counter()
    state = settle(case)
    system = case.system(state)
    period = system.forcing_period
    t_eval = period * np.arange(periods + 1)
    ref, ref_info = check_reference(case, system, t_eval)
    out: dict[str, Any] = {
        "name": case.name,
        "description": case.description,
        "params": case.params,
        "initial_state": dict(zip(case.state_keys, map(float, state), strict=True)),
        "forcing_period_s": period,
        "periods": periods,
        "positions": list(case.positions),
        "state_scale": system.state_scale.tolist(),
        "reference": ref_info,
        "integrators": {},
    }
    for kind in INTEGRATORS:
        rtol, scan = choose_rtol(kind, case, system, t_eval, ref, target)
        walls, run = time_runs(kind, case, system, t_eval, rtol, repeats)
        median = statistics.median(walls)
        out["integrators"][kind] = {
            "rtol": rtol,
            "atol_relative_to_state_scale": rtol,
            "error": max_error(run.positions, ref.positions),
            "impacts": run.impacts,
            "rhs_evaluations_per_period": run.rhs_evaluations / periods,
            "runs": len(walls),
            "wall_median_s": median,
            "wall_min_s": min(walls),
            "wall_max_s": max(walls),
            "wall_per_period_s": median / periods,
            "scan": scan,
        }
        err = out["integrators"][kind]["error"]
        print(
            f"  {case.name:8s} {kind:10s} rtol {rtol:8.2e}  error {err:.2e}"
            f"  {median / periods * 1e6:10.1f} us/period  ({len(walls)} runs)",
            file=sys.stderr,
            flush=True,
        )
    ints = out["integrators"]
    fast = ints["fast"]["wall_median_s"]
    # the floor of `fast`: its right-hand-side calls per period at the cost of one call,
    # and its distance to it, in rounds that each take both (floor_rounds)
    fl = floor_rounds(case, system, state, t_eval, ints["fast"]["rtol"], rounds)
    out["floor_rounds"] = fl["rounds"]
    out["rhs_call_s"] = fl["rhs_call_s"]
    out["rhs_chained_call_s"] = fl["rhs_chained_call_s"]
    calls = ints["fast"]["rhs_evaluations_per_period"]
    out["fast_floor_per_period_s"] = calls * fl["rhs_call_s"]["median"]
    out["fast_over_floor"] = fl["fast_over_floor"]
    out["target_fast_over_floor"] = 2.0
    out["fast_over_chained_floor"] = fl["fast_over_chained_floor"]
    out["free_flight"] = free_flight(case, periods, ints["fast"]["rtol"], rounds)
    out["fast_call_s"] = call_cost(system, ints["fast"]["rtol"], repeats)
    out["speedup_fast_vs_scipy_loop"] = ints["scipy_loop"]["wall_median_s"] / fast
    out["speedup_fast_vs_accurate"] = ints["accurate"]["wall_median_s"] / fast
    out["target_fast_vs_scipy_loop"] = 100.0
    out["target_met"] = out["speedup_fast_vs_scipy_loop"] >= 100.0
    out["bench_wall_s"] = time.perf_counter() - start
    return out


# ---------------------------------------------------------------------------- output
def _fmt_time(s: float) -> str:
    if s >= 1e-3:
        return f"{s * 1e3:.3g} ms"
    return f"{s * 1e6:.3g} µs"


def markdown(report: dict[str, Any]) -> str:
    meta = report["meta"]
    lines = [
        "# Engine benchmark: wall time per forcing period at equal accuracy",
        "",
        f"Target error {meta['target_error']:g} (max stroboscopic position error vs "
        f"`accurate` at rtol {REFERENCE_RTOL:g}, normalised by the reference's max |position|), "
        f"{meta['periods']} forcing periods from a state on the attractor; median of "
        f">= {meta['repeats']} runs after a warm-up.  {meta['date']}, {meta['cpu_count']} CPUs, "
        f"Python {meta['python']}, numpy {meta['numpy']}, scipy {meta['scipy']}, "
        f"numba {meta['numba']}, commit {meta['git_commit'][:10]}.",
        "",
        "| case | integrator | rtol | error | impacts | rhs calls / period | wall time / period "
        "| time / `fast` time |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for case in report["cases"]:
        fast = case["integrators"]["fast"]["wall_median_s"]
        for kind in INTEGRATORS:
            r = case["integrators"][kind]
            lines.append(
                f"| {case['name']} | {LABELS[kind]} | {r['rtol']:.2g} | {r['error']:.2g} | "
                f"{r['impacts']} | {r['rhs_evaluations_per_period']:.0f} | "
                f"{_fmt_time(r['wall_per_period_s'])} | "
                f"{r['wall_median_s'] / fast:.3g}x |"
            )
    lines += ["", "| case | `fast` vs scipy loop | `fast` vs `accurate` | target (>= 100x) |"]
    lines += ["|---|---:|---:|---|"]
    for case in report["cases"]:
        met = "met" if case["target_met"] else "NOT met"
        lines.append(
            f"| {case['name']} | {case['speedup_fast_vs_scipy_loop']:.3g}x | "
            f"{case['speedup_fast_vs_accurate']:.3g}x | {met} |"
        )
    lines.append("")
    rounds = report["cases"][0]["floor_rounds"] if report["cases"] else 0
    lines += [
        "Distance of `fast` to its floor: its right-hand-side calls per period times the cost "
        "of one compiled call, in a loop of calls spread over one forcing period.  Taken in "
        f"{rounds} rounds, each one `fast` run and at once a loop of as many calls as it made: "
        "the figures are the medians over the rounds (min-max in brackets), the ratio that of "
        "the rounds' own ratios.  The target is judged on that floor.  Within a Runge-Kutta "
        "step each stage's state depends on the stages before it, so the calls cannot "
        "overlap as they do in that loop; the last two columns measure a call in a loop "
        "where each call waits for the one before (in the same rounds), and `fast`'s "
        "distance to that floor.  The last column is `fast`'s distance to its floor on the "
        "same model with the obstacle out of reach (settled, at the same rtol, in as many "
        "rounds): the step loop without an event, so the difference from the impacting "
        "case is what its events cost.",
        "",
        "| case | rhs call | floor / period | `fast` / period | `fast` / floor | target (<= 2x) "
        "| chained rhs call | `fast` / chained floor | `fast` / floor, free flight |",
        "|---|---:|---:|---:|---:|---|---:|---:|---:|",
    ]
    for case in report["cases"]:
        ratio = case["fast_over_floor"]["median"]
        lines.append(
            f"| {case['name']} | {_ns(case['rhs_call_s'])} | "
            f"{_fmt_time(case['fast_floor_per_period_s'])} | "
            f"{_fmt_time(case['integrators']['fast']['wall_per_period_s'])} | "
            f"{_ratio(case['fast_over_floor'])} | "
            f"{'met' if ratio <= case['target_fast_over_floor'] else 'NOT met'} | "
            f"{_ns(case['rhs_chained_call_s'])} | {_ratio(case['fast_over_chained_floor'])} | "
            f"{_ratio(case['free_flight']['fast_over_floor'])} |"
        )
    lines.append("")
    for case in report["cases"]:
        c = case["fast_call_s"]
        run = case["integrators"]["fast"]["wall_median_s"]
        lines.append(
            f"A `fast` `simulate` call of one step (1e-6 of a period) on the {case['name']} "
            f"takes {c['median'] * 1e6:.3g} µs ({c['min'] * 1e6:.3g}-{c['max'] * 1e6:.3g}): "
            f"what each run above pays besides its steps, {100 * c['median'] / run:.2g} % of "
            "its time."
        )
    lines.append("")
    for case in report["cases"]:
        lines.append(f"- **{case['name']}**: {case['description']}.")
    lines.append("")
    return "\n".join(lines)


def _ns(c: dict[str, float]) -> str:
    """A call's cost: median (min-max), ns."""
    return f"{c['median'] * 1e9:.1f} ns ({c['min'] * 1e9:.1f}-{c['max'] * 1e9:.1f})"


def _ratio(r: dict[str, float]) -> str:
    """A ratio over the rounds: median (min-max)."""
    return f"{r['median']:.3g}x ({r['min']:.3g}-{r['max']:.3g})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="JSON result file")
    ap.add_argument("--md", type=Path, default=DEFAULT_MD, help="Markdown table file")
    ap.add_argument("--periods", type=int, default=50, help="forcing periods per run")
    ap.add_argument("--repeats", type=int, default=5, help="minimum timed runs per integrator")
    ap.add_argument("--target", type=float, default=1e-8, help="error every integrator must reach")
    ap.add_argument(
        "--floor-rounds", type=int, default=31, help="rounds of the distance to the floor"
    )
    ap.add_argument(
        "--cases", nargs="+", choices=[c.name for c in CASES], default=[c.name for c in CASES]
    )
    args = ap.parse_args(argv)
    if args.periods < 1 or args.repeats < 1 or args.floor_rounds < 1:
        ap.error("--periods, --repeats and --floor-rounds must be >= 1")

    start = time.perf_counter()
    cases = [
        bench_case(c, args.periods, args.repeats, args.target, args.floor_rounds)
        for c in CASES
        if c.name in args.cases
    ]
    report = {
        "meta": stamp(
            periods=args.periods,
            repeats=args.repeats,
            floor_rounds=args.floor_rounds,
            target_error=args.target,
            reference=f"simulate(engine='accurate', rtol={REFERENCE_RTOL:g})",
            rtol_scan=list(RTOL_SCAN),
            rtol_rule="loosest rtol with error <= target whose next tighter rtol also passes",
            total_wall_s=None,
        ),
        "cases": cases,
    }
    report["meta"]["total_wall_s"] = time.perf_counter() - start
    table = markdown(report)
    for path, text in ((args.out, json.dumps(report, indent=2) + "\n"), (args.md, table)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
