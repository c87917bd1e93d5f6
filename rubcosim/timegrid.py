"""When a scenario's outputs are recorded: the output grid and the stroboscopic
(Poincare) times.

Both the monolithic engines (:mod:`rubcosim.reference`) and the co-simulation
(:mod:`rubcosim.orchestrator`) record there; this module imports neither.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def strobe_times(scenario: Any) -> np.ndarray:
    """Fixed-phase section t = (2 pi k + phase)/w (s) after ``sim.poincare_discard``,
    up to ``sim.t_end``, for a :class:`rubcosim.scenario.Scenario`."""
    sim = scenario.sim
    period = scenario.graph.scales.forcing_period
    shift = sim["poincare_phase"] / (2.0 * math.pi) * period
    first = math.ceil((sim["t_start"] + sim["poincare_discard"] - shift) / period - 1e-9)
    last = math.floor((sim["t_end"] - shift) / period + 1e-9)
    return shift + period * np.arange(first, last + 1)


def output_grid(t_start: float, t_end: float, step: float) -> np.ndarray:
    """Uniform grid from t_start to t_end inclusive (the last point is t_end)."""
    n = int(math.floor((t_end - t_start) / step + 1e-9))
    grid = np.minimum(t_start + step * np.arange(n + 1), t_end)
    if grid[-1] < t_end - 1e-12 * max(1.0, abs(t_end)):
        grid = np.append(grid, t_end)
    else:
        grid[-1] = t_end
    return grid


def output_times(scenario: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sorted union of the output grid and the stroboscopic times, and where each
    of the two lies in it (the reference run records the same times)."""
    sim = scenario.sim
    grid = output_grid(sim["t_start"], sim["t_end"], sim["output_step"])
    strobe = strobe_times(scenario)
    both = np.concatenate((grid, strobe))
    order = np.argsort(both, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return both[order], rank[: grid.size], rank[grid.size :]
