"""The engine benchmark's cases (``bench_engines.py``): each model as rubcosim units and
as the plain scipy ``solve_ivp`` event loop a user would write, and one timed run of
either on the benchmark grid."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from rubcosim.components.oscillator import free_acceleration, impact_velocity
from rubcosim.components.rotor import jeffcott_force
from rubcosim.components.stator import contact_geometry, rigid_impact
from rubcosim.reference import System, build_system, make_unit, simulate

MAX_EVENTS = 100_000


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
