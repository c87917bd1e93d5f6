"""When a scenario's outputs are recorded: the stroboscopic (Poincare) times.

Both the monolithic runs (:mod:`rubcosim.runner`) and the co-simulation
(:mod:`rubcosim.orchestrator.assembly`) record there; this module imports neither.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def strobe_times(scenario: Any) -> np.ndarray:
    """Fixed-phase section t = (2 pi k + phase)/w (s) after ``sim.poincare_discard``,
    up to ``sim.t_end``, for a :class:`rubcosim.scenario.Scenario`."""
    sim = scenario.sim
    period = scenario.system.forcing_period
    shift = sim["poincare_phase"] / (2.0 * math.pi) * period
    first = math.ceil((sim["t_start"] + sim["poincare_discard"] - shift) / period - 1e-9)
    last = math.floor((sim["t_end"] - shift) / period + 1e-9)
    return shift + period * np.arange(first, last + 1)
