"""Stroboscopic Poincaré maps on the ``fast`` engine, compiled, one point or many.

The section is the fixed forcing phase ``t = t0 + k T`` (T the forcing
period).  Each period is one call of the ``fast`` engine's compiled
integrator from inside a compiled loop, so a sweep or a cell mapping pays no
Python per period.  The discrete mode (free, sliding, stuck...) is carried
from one period to the next with the state.

Impacts per period count rigid impacts and contact onsets of elastic stops
and stators (``KIND_IMPACT`` and ``KIND_CONTACT_ON`` events): the ``m`` of an
``n-m`` motion.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np

from rubcosim.reference.assemble import System
from rubcosim.reference.core import STATUS_MESSAGES, STATUS_OK
from rubcosim.reference.specialize import compiled_model

from .errors import MapError

DEFAULT_RTOL = 1e-9
STROBE_KERNELS = "rubcosim.analysis.strobe_kernels"


def kernels(system: System) -> ModuleType:
    """The compiled stroboscopic loops (:mod:`.strobe_kernels`): one module for every
    model (the model's own kernels: :func:`model_of`)."""
    return importlib.import_module(STROBE_KERNELS)


def model_of(system: System) -> tuple[Any, ...]:
    """``system``'s parameters and model tuple, as the compiled loops take them."""
    return np.array(system.p, dtype=float), compiled_model(system)


def obstacle_gaps(system: System, states: np.ndarray, mode: int) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance to the nearest rigid obstacle of ``system`` and its rate, for
    each state row (in ``mode``)."""
    Y = np.ascontiguousarray(np.atleast_2d(np.asarray(states, dtype=float)))
    gap, rate = np.empty(Y.shape[0]), np.empty(Y.shape[0])
    kernels(system).obstacle_gaps(Y, mode, *model_of(system), gap, rate)
    return gap, rate


DEFAULT_MAX_EVENTS = 20_000  # per forcing period: a chattering sequence stays well below


def admissible(smap: StroboscopicMap, states: np.ndarray) -> np.ndarray:
    """Whether each state (row, in the system's initial mode) is outside every rigid
    obstacle: a state beyond a rigid stop or stator is not a state of the system."""
    gap, _ = obstacle_gaps(smap.system, states, smap.system.mode0)
    return gap >= 0.0


@dataclass(frozen=True)
class Orbit:
    """Stroboscopic samples of a motion: ``points[k]`` is the state at ``t0 + (skip + k + 1) T``.

    ``impacts[k]`` counts the impacts (and contact onsets) in the period
    ending at ``points[k]``; ``modes[k]`` is the discrete mode there (0 free;
    else in sustained contact, or stuck).  ``status`` is the engine's (0: ok); on failure
    ``points`` holds only the periods done.
    """

    points: np.ndarray
    impacts: np.ndarray
    modes: np.ndarray
    mode: int
    status: int
    message: str
    period: float
    impact_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    impact_states: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    t0: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK

    @property
    def impact_phases(self) -> np.ndarray:
        """The impact section (the book's Poincaré section II, the impact surface): the
        forcing phase of each impact of the kept periods, rad in [0, 2 pi); the state
        just after each impact is ``impact_states``."""
        frac = np.mod((self.impact_times - self.t0) / self.period, 1.0)
        return 2.0 * math.pi * frac

    @property
    def final_state(self) -> np.ndarray:
        return self.points[-1]


class StroboscopicMap:
    """The fixed-phase Poincaré map of a monolithic system (no delay).

    ``rtol`` is the ``fast`` engine's relative tolerance; the absolute one is
    ``rtol`` times each state's scale (as in :func:`rubcosim.reference.simulate.simulate`).
    """

    def __init__(
        self,
        system: System,
        rtol: float = DEFAULT_RTOL,
        max_events: int = DEFAULT_MAX_EVENTS,
    ) -> None:
        if system.has_delay:
            raise MapError(
                "units.controller: a delayed-feedback system has an infinite-dimensional state "
                "(its history); stroboscopic maps, sweeps and cell mapping take delay-free "
                "systems only"
            )
        if not (isinstance(rtol, float | int) and 1e-14 <= rtol < 1.0):
            raise MapError(f"rtol = {rtol!r} must be in [1e-14, 1)")
        if not (isinstance(max_events, int) and max_events >= 1):
            raise MapError(f"max_events = {max_events!r} must be a positive integer")
        period = system.forcing_period
        if not (math.isfinite(period) and period > 0.0):
            raise MapError("the system has no forcing period: no stroboscopic section")
        self.system = system
        self.period = period
        self.rtol = float(rtol)
        self.max_events = max_events
        self.atol = np.ascontiguousarray(self.rtol * system.state_scale)
        self.scale = np.asarray(system.state_scale, dtype=float)

    @property
    def _kernels(self) -> ModuleType:
        """This model's compiled loops (a property: a map is pickled for worker processes,
        a module cannot be)."""
        return kernels(self.system)

    @property
    def n_state(self) -> int:
        return self.system.n_state

    def orbit(
        self,
        y0: np.ndarray | None = None,
        *,
        skip: int = 0,
        keep: int = 1,
        mode: int | None = None,
        t0: float = 0.0,
        max_section: int | None = None,
    ) -> Orbit:
        """Iterate the map ``skip + keep`` times from ``y0`` (default: the system's initial
        state at ``t0``) and keep the last ``keep`` points, and the impact section of the
        kept periods (at most ``max_section`` impacts, default 16 per period)."""
        if not (isinstance(skip, int) and skip >= 0):
            raise MapError(f"skip = {skip!r} must be an integer >= 0")
        if not (isinstance(keep, int) and keep >= 1):
            raise MapError(f"keep = {keep!r} must be an integer >= 1")
        y = self._state(y0)
        m = self.system.mode0 if mode is None else int(mode)
        points = np.full((keep, self.n_state), np.nan)
        impacts = np.zeros(keep, dtype=np.int64)
        modes = np.zeros(keep, dtype=np.int64)
        cap = 16 * keep if max_section is None else int(max_section)
        imp_t = np.full(cap, np.nan)
        imp_y = np.full((cap, self.n_state), np.nan)
        imp_n = np.zeros(1, dtype=np.int64)
        status, done, m_end = self._kernels.strobe_run(
            y,
            m,
            float(t0),
            self.period,
            skip,
            keep,
            *model_of(self.system),
            self.rtol,
            self.atol,
            math.inf,
            self.max_events,
            points,
            impacts,
            modes,
            imp_t,
            imp_y,
            imp_n,
        )
        kept = max(0, done - skip)
        n_sec = min(int(imp_n[0]), cap)
        message = STATUS_MESSAGES[status]
        if status != STATUS_OK:
            message = f"{message} (in forcing period {done + 1})"
        return Orbit(
            points[:kept],
            impacts[:kept],
            modes[:kept],
            int(m_end),
            int(status),
            message,
            self.period,
            imp_t[:n_sec],
            imp_y[:n_sec],
            float(t0),
        )

    def map(
        self, states: np.ndarray, periods: int = 1, modes: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Map many states (rows) through ``periods`` periods from phase 0.

        Returns ``(images, modes, impacts, status)``; a row whose run failed
        (status != 0) is NaN.
        """
        Y0 = np.ascontiguousarray(np.atleast_2d(np.asarray(states, dtype=float)))
        if Y0.shape[1] != self.n_state:
            raise MapError(f"states have {Y0.shape[1]} columns; the system has {self.n_state}")
        if not (isinstance(periods, int) and periods >= 1):
            raise MapError(f"periods = {periods!r} must be an integer >= 1")
        N = Y0.shape[0]
        m0 = np.full(N, self.system.mode0, dtype=np.int64) if modes is None else modes
        m0 = np.ascontiguousarray(m0, dtype=np.int64)
        Y1 = np.empty_like(Y0)
        m1 = np.empty(N, dtype=np.int64)
        impacts = np.empty(N, dtype=np.int64)
        status = np.empty(N, dtype=np.int64)
        self._kernels.map_many(
            Y0,
            m0,
            0.0,
            self.period,
            periods,
            *model_of(self.system),
            self.rtol,
            self.atol,
            math.inf,
            self.max_events,
            Y1,
            m1,
            impacts,
            status,
        )
        return Y1, m1, impacts, status

    def _state(self, y0: np.ndarray | None) -> np.ndarray:
        y = self.system.y0 if y0 is None else np.asarray(y0, dtype=float)
        if y.shape != (self.n_state,):
            raise MapError(f"y0 has shape {y.shape}; the system's state has {self.n_state}")
        if not np.all(np.isfinite(y)):
            raise MapError("y0 is not finite")
        return np.ascontiguousarray(y, dtype=float)
