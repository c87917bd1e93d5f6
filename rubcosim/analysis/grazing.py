"""Grazing: where a non-impacting periodic motion first touches the obstacle, and the
square-root law of the Poincaré map there.

The *free* system is the scenario with its obstacle taken away (a rigid
stop becomes no stop; a stator's clearance is made huge), so its orbit goes
on through the obstacle and the signed minimum gap along its periodic orbit
is a smooth function of the parameter.  Grazing is that minimum crossing
zero; there the normal velocity (the gap's rate) is zero, because the gap
is at a minimum.  The gap is the obstacle's event function evaluated by the
model's own compiled code on the free orbit, sampled densely over a period
and refined by a parabola through the smallest sample and its neighbours.

Square-root law (Nordmark; the book's zero-time discontinuity map): at the
grazing parameter, start from the grazing orbit's stroboscopic point moved
so that the free orbit penetrates the obstacle by a depth ``delta``; the
impacting map then differs from the free map by ``C sqrt(delta)``.  The
exponent is fitted on a log-log line over depths from about 1e-7 to 1e-3 of
the length scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import brentq

from rubcosim.reference import system as S
from rubcosim.reference.assemble import System
from rubcosim.reference.simulate import simulate
from rubcosim.scenario import Scenario

from .errors import AnalysisError
from .floquet import FLOQUET_RTOL, floquet
from .maps import StroboscopicMap, obstacle_gaps

SAMPLES_PER_PERIOD = 4000
DEPTHS = np.logspace(-7, -3, 9)  # penetration depths for the fit, in length scales
# a deviation below this (state scales) is the integration's noise: the contact was not
# resolved, and the depth is left out of the fit
UNRESOLVED = 1e-10


def obstacle_gap(system: System, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance to the nearest rigid obstacle of ``system`` and its rate, for
    each state row (free mode)."""
    return obstacle_gaps(system, states, S.MODE_FREE)


def free_params(system: System) -> dict[str, Any]:
    """The parameters (for :meth:`Scenario.with_params`) that take the obstacle away: a
    rigid or elastic stop of an impact oscillator, a stator of any contact law."""
    oscillator = system.units.get("oscillator")
    if oscillator is not None and oscillator.type == "impact_oscillator":
        if oscillator.params["stop"] == "none":
            raise AnalysisError("oscillator.stop: none, so nothing to graze")
        return {"oscillator.stop": "none"}
    stator = system.units.get("stator")
    if stator is None or stator.declaration.contact is None:
        raise AnalysisError("units.stator: grazing is studied on a stop or a stator")
    return {"stator.clearance": 1e6 * stator.params["clearance"]}


def expected_exponent(system: System) -> float:
    """The exponent of the map's deviation against the penetration depth at grazing: 1/2
    at a rigid obstacle (Nordmark's square-root law), 3/2 at an elastic one, where the
    force is continuous and only its derivative jumps (the velocity a contact of depth d
    changes is about k d sqrt(d))."""
    oscillator = system.units.get("oscillator")
    if oscillator is not None and oscillator.type == "impact_oscillator":
        return 0.5 if oscillator.params["stop"].startswith("rigid") else 1.5
    stator = system.units.get("stator")
    return 0.5 if stator is not None and stator.declaration.contact.kind == "rigid" else 1.5


@dataclass(frozen=True)
class GapMinimum:
    gap: float  # signed minimum gap along one period, m (or the model's length unit)
    rate: float  # the gap's rate there (the normal velocity)
    time: float  # when, from the period's start


def min_gap(
    obstacle: System, free: System, y: np.ndarray, rtol: float = FLOQUET_RTOL
) -> GapMinimum:
    """The smallest gap to ``obstacle``'s obstacle along one forcing period of the
    ``free`` system's orbit from ``y`` (at phase 0)."""
    T = free.forcing_period
    t = np.linspace(0.0, T, SAMPLES_PER_PERIOD + 1)
    sys0 = System(**{**free.__dict__, "y0": np.asarray(y, dtype=float)})
    res = simulate(sys0, T, t_eval=t, engine="fast", rtol=rtol)
    if not res.ok:
        raise AnalysisError(f"the free orbit failed: {res.message}")
    idx = [res.output_names.index(n) for n in free.state_names]
    gap, rate = obstacle_gap(obstacle, res.outputs[:, idx])
    i = int(np.clip(np.argmin(gap), 1, gap.size - 2))
    g0, g1, g2 = gap[i - 1 : i + 2]
    curv = g0 - 2.0 * g1 + g2
    shift = 0.5 * (g0 - g2) / curv if curv > 0.0 else 0.0
    shift = float(np.clip(shift, -1.0, 1.0))
    refined = g1 - 0.25 * (g0 - g2) * shift
    dt = t[1] - t[0]
    return GapMinimum(
        float(min(refined, g1)),
        float(np.interp(t[i] + shift * dt, t, rate)),
        float(t[i] + shift * dt),
    )


@dataclass
class Grazing:
    """A located grazing: parameter value, the free periodic orbit's stroboscopic point
    there, the normal velocity at the touching point, and the square-root law fit."""

    param: str
    value: float
    state: np.ndarray
    normal_velocity: float  # relative to the system's velocity scale
    depths: np.ndarray
    deviations: np.ndarray
    exponent: float
    expected: float = 0.5  # 1/2 at a rigid obstacle, 3/2 at an elastic one

    def as_dict(self) -> dict[str, Any]:
        return {
            "parameter": self.param,
            "value": self.value,
            "state": self.state.tolist(),
            "normal_velocity_relative": self.normal_velocity,
            "sqrt_law": {
                "depths": self.depths.tolist(),
                "deviations": self.deviations.tolist(),
                "exponent": self.exponent,
                "expected": self.expected,
            },
        }


def _systems(scenario: Scenario, param: str, value: float) -> tuple[System, System]:
    """The system at ``param = value`` and the same without its obstacle.  The free
    system keeps the obstacle system's scales: a stator taken away by a huge clearance
    would otherwise size every tolerance by that clearance (Newton's on the free orbit,
    the engine's), far coarser than the gap being measured."""
    with_obstacle = scenario.with_params({param: float(value)})
    free = with_obstacle.with_params(free_params(with_obstacle.system)).system
    obstacle = with_obstacle.system
    free = replace(free, state_scale=obstacle.state_scale, velocity_scale=obstacle.velocity_scale)
    return obstacle, free


def _free_periodic_point(free: System, guess: np.ndarray | None) -> np.ndarray:
    smap = StroboscopicMap(free, FLOQUET_RTOL)
    if guess is None:
        orbit = smap.orbit(skip=300, keep=1)
        if not orbit.ok:
            raise AnalysisError(f"the free system's orbit failed: {orbit.message}")
        guess = orbit.final_state
    return floquet(smap, guess, 1).state


def locate(
    scenario: Scenario,
    param: str,
    lo: float,
    hi: float,
    xtol: float = 1e-10,
    guess: np.ndarray | None = None,
) -> tuple[float, np.ndarray, float]:
    """The parameter in ``[lo, hi]`` where the free period-1 orbit's minimum gap is
    zero, to ``xtol`` relative; returns ``(value, state, normal velocity)``.  ``guess``:
    a state near the free orbit at ``lo`` (default: where the free system settles)."""
    cache: dict[float, np.ndarray] = {} if guess is None else {lo: np.asarray(guess)}

    def gap_at(mu: float) -> float:
        obstacle, free = _systems(scenario, param, mu)
        y = _free_periodic_point(free, next(iter(cache.values()), None))
        cache[mu] = y
        return min_gap(obstacle, free, y).gap / float(obstacle.state_scale[0])

    g_lo, g_hi = gap_at(lo), gap_at(hi)
    if g_lo * g_hi > 0.0:
        raise AnalysisError(
            f"{param}: the free orbit's minimum gap has one sign on [{lo:g}, {hi:g}] "
            f"({g_lo:.3g}, {g_hi:.3g} length scales): no grazing there"
        )
    span = abs(hi - lo)
    value = brentq(gap_at, lo, hi, xtol=xtol * max(span, abs(lo), abs(hi)), rtol=1e-15)
    obstacle, free = _systems(scenario, param, value)
    y = _free_periodic_point(free, cache.get(value))
    m = min_gap(obstacle, free, y)
    return float(value), y, m.rate / obstacle.velocity_scale


def sqrt_law(
    scenario: Scenario, param: str, value: float, y_graze: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Deviation of the impacting map from the free map against penetration depth at the
    grazing point, and the fitted exponent (expected 0.5)."""
    obstacle, free = _systems(scenario, param, value)
    imp_map = StroboscopicMap(obstacle, FLOQUET_RTOL)
    free_map = StroboscopicMap(free, FLOQUET_RTOL)
    scale = obstacle.state_scale
    length = float(scale[0])
    # the direction that pushes the free orbit into the obstacle: along the gradient of
    # the minimum gap over the section (taken by differences)
    grad = np.empty(y_graze.size)
    h = 1e-6
    base = min_gap(obstacle, free, y_graze).gap
    for j in range(y_graze.size):
        e = np.zeros_like(y_graze)
        e[j] = h * scale[j]
        grad[j] = (min_gap(obstacle, free, y_graze + e).gap - base) / h
    direction = -grad / np.linalg.norm(grad)
    depths, devs = [], []
    for target in DEPTHS:
        s = target * length / np.linalg.norm(grad)
        y = y_graze + s * direction * scale
        depth = -min_gap(obstacle, free, y).gap / length
        if depth <= 0.0:
            continue
        a = imp_map.orbit(y, keep=1)
        b = free_map.orbit(y, keep=1)
        if not (a.ok and b.ok) or a.impacts[0] < 1:
            continue
        dev = float(np.max(np.abs(a.final_state - b.final_state) / scale))
        if dev < UNRESOLVED:
            # a contact too shallow for the engine: it locates an elastic stop's contact
            # only where a step ends inside it, and the map is then the free one
            continue
        depths.append(depth)
        devs.append(dev)
    if len(depths) < 4:
        raise AnalysisError("too few impacting perturbations to fit the square-root law")
    slope = float(np.polyfit(np.log(depths), np.log(devs), 1)[0])
    return np.array(depths), np.array(devs), slope


def brackets(values: np.ndarray, impacts: np.ndarray, status: np.ndarray) -> list[tuple]:
    """Neighbouring sweep values between which the motion starts (or stops) impacting:
    ``impacts`` is (values, periods)."""
    hits = impacts.sum(axis=1) > 0
    out = []
    for i in range(values.size - 1):
        if status[i] == 0 and status[i + 1] == 0 and hits[i] != hits[i + 1]:
            out.append((float(values[i]), float(values[i + 1])))
    return out


def grazing(scenario: Scenario, param: str, lo: float, hi: float, xtol: float = 1e-10) -> Grazing:
    """Locate the grazing of ``scenario`` (its overrides kept) between ``param = lo`` and
    ``hi`` (the parameter's unit) and fit the square-root law there."""
    value, y, vn = locate(scenario, param, lo, hi, xtol)
    depths, devs, slope = sqrt_law(scenario, param, value, y)
    if not math.isfinite(slope):
        raise AnalysisError("the square-root law fit failed")
    expected = expected_exponent(scenario.with_params({param: value}).system)
    return Grazing(param, value, y, vn, depths, devs, slope, expected)


def sweep_grazings(scenario: Scenario, result: Any, limit: int = 5) -> list[dict[str, Any]]:
    """The grazings between neighbouring values of a sweep (``SweepResult``) of
    ``scenario`` where its first direction starts or stops impacting, at most ``limit``,
    as dicts (``Grazing.as_dict``)."""
    first = next(iter(result.points))
    found = []
    for lo, hi in brackets(result.values, result.impacts[first], result.status[first])[:limit]:
        lo, hi = min(lo, hi), max(lo, hi)
        found.append(grazing(scenario, result.param.name, lo, hi).as_dict())
    return found
