"""The n-periodic orbits of a delay-free scenario as zeros of one function, for Newton.

An n-periodic orbit at parameter value ``mu`` is a zero of ``G(y, mu) = P^n(y; mu) - y``,
``P`` the stroboscopic map at forcing phase 0 (:mod:`.maps`), ``y`` the state on that
section.  Its derivative in ``y`` is the monodromy matrix less the identity, from the
variational equations with the saltation matrix at every event
(:func:`.lyapunov.monodromy`): the Floquet multipliers are its eigenvalues.  Its
derivative in ``mu`` is a central difference of the map, whose images come from the
same compiled engine.  A parameter that changes the forcing frequency changes the
section's period too: every value has its own system (:meth:`Scenario.with_params`,
which validates the value against the parameter's range).

The map is smooth only while nearby orbits keep this one's impacts: the impacts of the
difference images are compared with the orbit's, and :attr:`Linearization.smooth` says
whether they agree (they do not near grazing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rubcosim.reference.assemble import System
from rubcosim.scenario import Scenario, ScenarioError

from .errors import AnalysisError, MapError
from .floquet import FLOQUET_RTOL
from .lyapunov import monodromy
from .maps import DEFAULT_MAX_EVENTS, StroboscopicMap

MU_STEP = 1e-6  # central difference in the parameter, relative to its scale
BACKTRACKS = 6  # halvings of a Newton step that does not lower the residual


@dataclass(frozen=True)
class Linearization:
    """``G``, ``dG/dy`` and ``dG/dmu`` at ``(y, mu)``; ``monodromy`` the n-period
    tangent matrix (``dG/dy + I``), ``impacts`` the orbit's impacts per n periods,
    ``smooth`` whether the difference images kept them."""

    residual: np.ndarray
    d_state: np.ndarray
    d_param: np.ndarray
    monodromy: np.ndarray
    impacts: int
    smooth: bool


class OrbitProblem:
    """``G(y, mu) = P^n(y; mu) - y`` for parameter ``param`` (``unit.name``) of
    ``scenario``, n = ``period`` forcing periods, the section in discrete ``mode``
    (default: the scenario's initial mode).  ``mu_scale`` sizes the parameter's
    difference step (its unit)."""

    def __init__(
        self,
        scenario: Scenario,
        param: str,
        period: int = 1,
        *,
        mode: int | None = None,
        rtol: float = FLOQUET_RTOL,
        max_events: int = DEFAULT_MAX_EVENTS,
        mu_scale: float = 1.0,
    ) -> None:
        if not isinstance(param, str) or param.count(".") != 1 or not all(param.split(".")):
            raise ScenarioError(f"--param {param!r}: expected unit.param")
        if not (isinstance(period, int) and period >= 1):
            raise AnalysisError(f"--period {period!r}: must be an integer >= 1")
        if not (isinstance(rtol, float | int) and 1e-14 <= rtol < 1e-6):
            raise AnalysisError(f"--rtol {rtol!r}: must be in [1e-14, 1e-6)")
        self.scenario = scenario
        self.param = param
        self.period = period
        self.rtol = float(rtol)
        self.max_events = max_events
        self.mu_scale = float(mu_scale)
        base = scenario.system
        if base.has_delay:
            raise MapError(
                "units.controller: continuation takes delay-free scenarios only (a delayed-"
                "feedback system's state is its whole history); `rubcosim lyapunov "
                "--uncontrolled` and `rubcosim control-study` take the delay system"
            )
        self.ip = tuple(base.ip)
        self.mode = base.mode0 if mode is None else int(mode)
        self.scale = np.asarray(base.state_scale, dtype=float)
        self.state_names = list(base.state_names)
        self._systems: dict[float, System] = {}

    def value(self) -> float:
        """The parameter's value in the scenario (SI units)."""
        unit, name = self.param.split(".")
        units = self.scenario.units
        if unit not in units:
            raise ScenarioError(f"--param {self.param}: the scenario has no unit {unit!r}")
        value = units[unit].get(name)
        if not isinstance(value, float | int) or isinstance(value, bool):
            raise ScenarioError(f"--param {self.param}: not a real parameter of the scenario")
        return float(value)

    def system(self, mu: float) -> System:
        """The scenario's system at ``mu`` (validated: a value out of the parameter's
        range is a :class:`ScenarioError` naming it)."""
        mu = float(mu)
        system = self._systems.get(mu)
        if system is None:
            system = self.scenario.with_params({self.param: mu}).system
            if tuple(system.ip) != self.ip:
                raise ScenarioError(f"--param {self.param}: changes the model's structure")
            if len(self._systems) > 64:
                self._systems.clear()
            self._systems[mu] = system
        return system

    def image(self, y: np.ndarray, mu: float) -> tuple[np.ndarray, int]:
        """``P^n(y; mu)`` and the impacts on the way; a run that fails is a MapError."""
        smap = StroboscopicMap(self.system(mu), self.rtol, self.max_events)
        orbit = smap.orbit(np.asarray(y, dtype=float), keep=self.period, mode=self.mode)
        if not orbit.ok:
            raise MapError(f"the map failed at {self.param} = {mu:.12g}: {orbit.message}")
        return orbit.final_state, int(orbit.impacts.sum())

    def section_orbit(self, y: np.ndarray, mu: float) -> np.ndarray:
        """The orbit's n states on the section: ``y, P(y), ..., P^(n-1)(y)``."""
        if self.period == 1:
            return np.asarray(y, dtype=float)[None, :]
        smap = StroboscopicMap(self.system(mu), self.rtol, self.max_events)
        orbit = smap.orbit(np.asarray(y, dtype=float), keep=self.period - 1, mode=self.mode)
        if not orbit.ok:
            raise MapError(f"the map failed at {self.param} = {mu:.12g}: {orbit.message}")
        return np.vstack((y, orbit.points))

    def linearize(self, y: np.ndarray, mu: float, with_param: bool = True) -> Linearization:
        """``G`` and its derivatives at ``(y, mu)``; without ``with_param``, ``dG/dmu`` is
        not computed (zeros) and the orbit counts as smooth."""
        system = self.system(mu)
        y = np.ascontiguousarray(y, dtype=float)
        if not np.all(np.isfinite(y)):
            raise MapError(f"a non-finite state at {self.param} = {mu:.12g}")
        phi, impacts, image, mode = monodromy(
            system, y, self.period, self.mode, self.rtol, self.max_events
        )
        if mode != self.mode:
            raise MapError(
                f"at {self.param} = {mu:.12g} the orbit ends its {self.period} period(s) in "
                f"mode {mode}, not in the section's mode {self.mode}"
            )
        d_param = np.zeros(y.size)
        smooth = True
        if with_param:
            h = MU_STEP * max(abs(mu), self.mu_scale)
            up, m_up = self.image(y, mu + h)
            down, m_down = self.image(y, mu - h)
            d_param = (up - down) / (2.0 * h)
            smooth = m_up == impacts and m_down == impacts
        return Linearization(image - y, phi - np.eye(y.size), d_param, phi, int(impacts), smooth)

    def scaled_residual(self, r: np.ndarray) -> float:
        """``|r|`` in state scales (the largest component)."""
        return float(np.max(np.abs(r) / self.scale))

    def newton(
        self, y: np.ndarray, mu: float, tol: float = 1e-10, max_iter: int = 20
    ) -> tuple[np.ndarray, Linearization, int]:
        """The orbit at fixed ``mu`` nearest ``y`` by Newton's method, damped: a step
        that does not lower the residual is halved (up to :data:`BACKTRACKS` times), so
        that a start a little away from a saddle does not leave for another orbit.
        Returns its state, its linearization there and the iterations; a MapError says
        how far Newton got."""
        y = np.array(y, dtype=float)
        lin = self.linearize(y, mu, with_param=False)
        res = best = self.scaled_residual(lin.residual)
        for k in range(max_iter + 1):
            if res < tol:
                return y, lin, k
            if k == max_iter:
                break
            step = np.linalg.solve(lin.d_state, lin.residual)
            for _ in range(BACKTRACKS + 1):
                try:
                    trial = self.linearize(y - step, mu, with_param=False)
                    trial_res = self.scaled_residual(trial.residual)
                except MapError:
                    trial_res = math.inf
                if trial_res < res:
                    break
                step = 0.5 * step
            if not math.isfinite(trial_res):
                break
            y, lin, res = y - step, trial, trial_res
            best = min(best, res)
        raise MapError(
            f"Newton did not converge to a {self.period}-periodic orbit at {self.param} = "
            f"{mu:.12g}: residual {res:.3g} state scales after {max_iter} iterations "
            f"(best {best:.3g}, tolerance {tol:g}); start nearer the orbit (--start) or "
            "settle longer (--settle)"
        )


def settled_start(problem: OrbitProblem, mu: float, settle: int) -> tuple[np.ndarray, int]:
    """The state on the section after ``settle`` periods from the scenario's initial
    state at ``mu``, and the discrete mode there (a rotor in sustained contact is not in
    free flight): a start on the attractor it settles onto."""
    system = problem.system(mu)
    smap = StroboscopicMap(system, problem.rtol, problem.max_events)
    orbit = smap.orbit(system.y0, skip=max(settle - 1, 0), keep=1, mode=system.mode0)
    if not orbit.ok:
        raise MapError(f"settling at {problem.param} = {mu:.12g} failed: {orbit.message}")
    return orbit.final_state, orbit.mode


def as_state(problem: OrbitProblem, y: Any) -> np.ndarray:
    """``y`` as a state of the problem's system (one finite number per state)."""
    arr = np.asarray(y, dtype=float).ravel()
    n = len(problem.state_names)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        names = ", ".join(problem.state_names)
        raise AnalysisError(f"--start: expected {n} finite numbers ({names})")
    return arr
