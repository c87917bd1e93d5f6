"""Pseudo-arclength continuation of n-periodic orbits in one parameter, through impacts.

The branch is the curve of zeros of ``G(y, mu) = P^n(y; mu) - y``
(:class:`.orbit_problem.OrbitProblem`) in the scaled unknowns ``u = (y / scale,
mu / mu_scale)``, ``scale`` the states' scales and ``mu_scale`` the length of the asked
range.  Keller's method: from a point ``u_k`` with unit tangent ``t_k``, predict
``u_k + ds t_k`` and correct by Newton on ``G = 0`` with ``t_k . (u - u_pred) = 0``;
the new tangent solves ``[dG/du; t_k^T] t = e`` (which keeps the orientation).  The
arclength step ``ds`` grows after a quick correction, shrinks after a slow one, and
halves when the corrector fails or the orbit's impacts per n periods change (the map is
not smooth across grazing).  Folds are passed like any other point: the parameter turns
and the branch goes on.

Every point carries its Floquet multipliers (the monodromy matrix's eigenvalues) and
Newton's residual; the special points between two points (fold, flip, Neimark-Sacker)
are located by :mod:`.bifurcation_points`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcosim.scenario import ScenarioError

from .bifurcation_points import SpecialPoint, locate_between, test_values
from .branch_grazing import branch_grazing
from .errors import AnalysisError, MapError
from .floquet import multipliers_of
from .orbit_problem import Linearization, OrbitProblem

NEWTON_TOL = 1e-10  # |G| in state scales
MAX_CORRECTOR = 8
FAST, SLOW = 3, 6  # corrector iterations below which ds grows, above which it shrinks
MIN_COS = 0.9  # the cosine of the largest turn of the tangent in one step


@dataclass(frozen=True)
class BranchPoint:
    """One orbit of the branch: ``param`` (the parameter's unit), ``state`` on the
    section, Floquet ``multipliers`` (largest modulus first), ``impacts`` per n
    periods, Newton's ``residual`` (state scales) and the corrector's ``iterations``."""

    param: float
    state: np.ndarray
    multipliers: np.ndarray
    impacts: int
    residual: float
    iterations: int

    @property
    def spectral_radius(self) -> float:
        return float(np.max(np.abs(self.multipliers)))

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0


@dataclass
class Branch:
    """A continued branch of n-periodic orbits: its points in arclength order, the
    special points located between them, and why the continuation stopped."""

    scenario: str
    param: str
    period: int
    state_names: list[str]
    points: list[BranchPoint] = field(default_factory=list)
    special: list[SpecialPoint] = field(default_factory=list)
    stop_reason: str = ""
    # every point's n states on the section (P^k of its state, k < n), when filled
    section_points: list[np.ndarray] = field(default_factory=list)
    cascade: Any = None  # the period-doubling cascade from this branch, when asked
    source: Any = field(default=None, repr=False)  # the Continuation that made it

    @property
    def params(self) -> np.ndarray:
        return np.array([p.param for p in self.points])

    @property
    def states(self) -> np.ndarray:
        return np.array([p.state for p in self.points]).reshape(len(self.points), -1)

    @property
    def stable(self) -> np.ndarray:
        return np.array([p.stable for p in self.points], dtype=bool)

    @property
    def multipliers(self) -> np.ndarray:
        return np.array([p.multipliers for p in self.points])

    def special_of(self, kind: str) -> list[SpecialPoint]:
        """The special points of ``kind`` (``"fold"``, ``"flip"``, ...), in branch order."""
        return [s for s in self.special if s.kind == kind]


@dataclass
class _Point:
    """A converged point in scaled unknowns, with what the next step needs."""

    u: np.ndarray
    lin: Linearization
    iterations: int
    residual: float
    jac: np.ndarray  # d(residual)/du, scaled: the rows of the corrector's matrix


class Continuation:
    """Continue the orbit of ``problem`` through ``start`` (a state near the orbit at
    ``mu0``) toward ``mu1`` (``step``, ``max_step``, ``min_step``: arclength steps in
    fractions of the range; ``locate_grazing``: locate where the branch stops at grazing)."""

    def __init__(
        self,
        problem: OrbitProblem,
        mu0: float,
        mu1: float,
        *,
        step: float = 0.02,
        max_step: float = 0.05,
        min_step: float = 1e-7,
        max_points: int = 500,
        locate_grazing: bool = True,
    ) -> None:
        if not (math.isfinite(mu0) and math.isfinite(mu1) and mu0 != mu1):
            raise AnalysisError("--from and --to: finite and different values")
        for name, v in (("--step", step), ("--max-step", max_step), ("--min-step", min_step)):
            if not (isinstance(v, float | int) and v > 0.0 and math.isfinite(v)):
                raise AnalysisError(f"{name} {v!r}: must be a positive number")
        if not (isinstance(max_points, int) and max_points >= 2):
            raise AnalysisError(f"--max-points {max_points!r}: must be an integer >= 2")
        self.problem = problem
        self.mu0, self.mu1 = float(mu0), float(mu1)
        self.lo, self.hi = min(mu0, mu1), max(mu0, mu1)
        self.mu_scale = abs(mu1 - mu0)
        self.scale = np.append(problem.scale, self.mu_scale)
        self.ds, self.max_step, self.min_step = step, max_step, min_step
        self.max_points = max_points
        self.locate_grazing = locate_grazing

    # scaled unknowns <-> (y, mu)
    def _u(self, y: np.ndarray, mu: float) -> np.ndarray:
        return np.append(y, mu) / self.scale

    def _split(self, u: np.ndarray) -> tuple[np.ndarray, float]:
        z = u * self.scale
        return z[:-1], float(z[-1])

    def _jacobian(self, lin: Linearization) -> np.ndarray:
        """``dG/du`` in scaled unknowns, G in state scales: n x (n + 1)."""
        s = self.problem.scale
        dy = lin.d_state * s[None, :] / s[:, None]
        dmu = lin.d_param * self.mu_scale / s
        return np.column_stack((dy, dmu))

    def evaluate(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, Linearization]:
        """The residual (state scales), its derivative in the scaled unknowns, and the
        linearization, at ``u``; raises MapError when the map fails."""
        y, mu = self._split(u)
        lin = self.problem.linearize(y, mu)
        return lin.residual / self.problem.scale, self._jacobian(lin), lin

    def tangent(self, a: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """The unit tangent at a point whose residual's derivative is ``a``; oriented
        along ``previous``, or toward ``mu1``."""
        n = a.shape[0]
        if previous is None:
            row = np.zeros(n + 1)
            row[-1] = 1.0
        else:
            row = previous
        rhs = np.zeros(n + 1)
        rhs[-1] = 1.0
        t = np.linalg.solve(np.vstack((a, row)), rhs)
        t /= np.linalg.norm(t)
        if previous is None and t[-1] * (self.mu1 - self.mu0) < 0.0:
            t = -t
        return t

    def correct(self, u_pred: np.ndarray, t: np.ndarray) -> _Point | None:
        """Newton on ``G = 0``, ``t . (u - u_pred) = 0`` from ``u_pred``; None when it does
        not converge in :data:`MAX_CORRECTOR` iterations or the map fails."""
        u = u_pred.copy()
        for k in range(MAX_CORRECTOR + 1):
            try:
                g, jac, lin = self.evaluate(u)
            except (MapError, ScenarioError, np.linalg.LinAlgError):
                return None  # a map that fails, or an iterate out of a parameter's range
            res = float(np.max(np.abs(g)))
            if res < NEWTON_TOL:
                return _Point(u, lin, k, res, jac)
            if k == MAX_CORRECTOR or not math.isfinite(res):
                return None
            a = np.vstack((jac, t))
            h = np.append(g, t @ (u - u_pred))
            try:
                u = u - np.linalg.solve(a, h)
            except np.linalg.LinAlgError:
                return None
        return None

    def outside(self, u: np.ndarray) -> str:
        """Why ``u`` leaves the region continued, other than the parameter's range
        (empty: it does not)."""
        return ""

    def _branch_point(self, pt: _Point) -> BranchPoint:
        y, mu = self._split(pt.u)
        lam = multipliers_of(pt.lin.monodromy)
        return BranchPoint(mu, y, lam, pt.lin.impacts, pt.residual, pt.iterations)

    def _at_bound(self, prev: _Point, t: np.ndarray, bound: float) -> _Point | None:
        """The point where the branch meets ``mu = bound``: the corrector with the
        hyperplane ``mu = bound`` instead of the arclength one."""
        y, mu = self._split(prev.u)
        ds = (bound - mu) / self.mu_scale / t[-1]
        e = np.zeros(t.size)
        e[-1] = 1.0
        u_pred = prev.u + ds * t
        u_pred[-1] = bound / self.mu_scale
        return self.correct(u_pred, e)

    def run(self, start: np.ndarray, progress: Callable[[float], None] | None = None) -> Branch:
        """The branch from ``start`` (refined by Newton at ``mu0``) until the parameter
        leaves the range, ``max_points`` points, or the step falls below ``min_step``."""
        pb = self.problem
        y0, lin, k = pb.newton(start, self.mu0, NEWTON_TOL)
        lin = pb.linearize(y0, self.mu0)
        cur = _Point(self._u(y0, self.mu0), lin, k, pb.scaled_residual(lin.residual),
                     self._jacobian(lin))  # fmt: skip
        branch = self.new_branch()
        if not lin.smooth:
            branch.points.append(self._branch_point(cur))
            branch.stop_reason = "the start is at grazing: nearby orbits change their impacts"
            return branch
        return self.march(branch, cur, self.tangent(cur.jac, None), progress)

    def new_branch(self) -> Branch:
        pb = self.problem
        return Branch(pb.scenario.name, pb.param, pb.period, pb.state_names, source=self)

    def march(
        self,
        branch: Branch,
        cur: _Point,
        t: np.ndarray,
        progress: Callable[[float], None] | None = None,
    ) -> Branch:
        """Add ``cur`` and the points after it along ``t`` to ``branch``."""
        branch.points.append(self._branch_point(cur))
        tests = test_values(branch.points[-1].multipliers, cur.jac, t)
        ds = self.ds
        self.rejected: tuple[float, _Point | None] | None = None  # nearest failed step
        while len(branch.points) < self.max_points:
            nxt = self.correct(cur.u + ds * t, t)
            ok = nxt is not None and nxt.lin.smooth and nxt.lin.impacts == cur.lin.impacts
            t_new = self.tangent(nxt.jac, t) if ok else t
            outside = self.outside(nxt.u) if ok else ""
            if outside:
                branch.stop_reason = outside
                break
            # a corrector that lands farther from the prediction than the step, or a
            # tangent that turns by more than ~25 degrees, may have jumped to another
            # branch (P^n has the fixed points of every divisor's orbits): a shorter step
            if ok and (np.linalg.norm(nxt.u - cur.u - ds * t) > ds or float(t_new @ t) < MIN_COS):
                ok = False
            if not ok:
                self.rejected = (self._split(cur.u + ds * t)[1], nxt)
                ds *= 0.5
                if ds < self.min_step:
                    branch.stop_reason = self._why_stopped(nxt, cur)
                    if self.locate_grazing and branch.stop_reason.startswith("grazing"):
                        found = branch_grazing(self, branch)
                        if found is not None:
                            branch.special.append(found)
                    break
                continue
            _, mu = self._split(nxt.u)
            if not (self.lo <= mu <= self.hi):
                end = self._at_bound(cur, t, self.hi if mu > self.hi else self.lo)
                if end is not None and end.lin.impacts == cur.lin.impacts:
                    self._accept(branch, cur, t, end, tests)
                    branch.stop_reason = "reached the end of the range"
                    break
                ds *= 0.5  # the bound's point did not converge from here: nearer first
                if ds < self.min_step:
                    branch.stop_reason = "reached the end of the range (its point did not converge)"
                    break
                continue
            tests = self._accept(branch, cur, t, nxt, tests, t_new)
            if progress is not None:
                progress(mu)
            cur, t = nxt, t_new
            self.rejected = None
            if nxt.iterations <= FAST:
                ds = min(ds * 1.5, self.max_step)
            elif nxt.iterations >= SLOW:
                ds *= 0.5
        else:
            branch.stop_reason = f"reached {self.max_points} points (--max-points)"
        return branch

    def _accept(
        self,
        branch: Branch,
        cur: _Point,
        t: np.ndarray,
        nxt: _Point,
        tests: np.ndarray,
        t_new: np.ndarray | None = None,
    ) -> np.ndarray:
        """Add ``nxt`` to the branch, and the special points between ``cur`` and it;
        returns the test functions at ``nxt``."""
        point = self._branch_point(nxt)
        t_new = self.tangent(nxt.jac, t) if t_new is None else t_new
        new_tests = test_values(point.multipliers, nxt.jac, t_new)
        index = len(branch.points) - 1
        for sp in locate_between(self, cur, t, nxt, tests, new_tests, index):
            branch.special.append(sp)
        branch.points.append(point)
        return new_tests

    def _why_stopped(self, nxt: _Point | None, cur: _Point) -> str:
        if nxt is None:
            return f"the corrector failed with the step below --min-step {self.min_step:g}"
        _, mu = self._split(cur.u)
        if not nxt.lin.smooth or nxt.lin.impacts != cur.lin.impacts:
            change = (
                f"{cur.lin.impacts} -> {nxt.lin.impacts}"
                if nxt.lin.impacts != cur.lin.impacts
                else "in orbits nearby"
            )
            return (
                f"grazing near {self.problem.param} = {mu:.10g}: the impacts per "
                f"{self.problem.period} period(s) change ({change}) and the map is not "
                "smooth there"
            )
        return "the step fell below --min-step"
