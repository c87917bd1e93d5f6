"""Two-parameter continuation of folds and flips of periodic orbits.

A fold (or flip) of an n-periodic orbit is a zero of the extended system

    G(y, mu1, mu2) = P^n(y; mu1, mu2) - y = 0,    psi(y, mu1, mu2) = det(M -+ I) = 0,

``M`` the monodromy matrix (variational equations with saltation matrices): n + 1
equations in n + 2 unknowns, a curve in the parameter plane.  It is followed by the same
pseudo-arclength stepper as a branch (:class:`.continuation.Continuation`), in the
scaled unknowns ``(y / scale, mu1 / range1, mu2 / range2)``; ``psi``'s derivatives are
central differences of the monodromy matrix (in the state, ``STATE_STEP`` scales; in each
parameter, :data:`.orbit_problem.MU_STEP` of its scale).  The curve starts at a special
point located on a one-parameter branch and runs over ``mu2``'s range while ``mu1`` stays
in its own.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rubcosim.scenario import ScenarioError

from .bifurcation_points import SpecialPoint
from .continuation import Branch, BranchPoint, Continuation, _Point
from .errors import AnalysisError, MapError
from .floquet import multipliers_of
from .orbit_problem import MU_STEP, Linearization, OrbitProblem

CURVE_KINDS = ("fold", "flip")
STATE_STEP = 1e-6  # central difference of psi in the state, in state scales
# psi's residual is divided by PSI_NOISE times prod(1 + |lambda|) at the start before it
# meets the corrector's tolerance: the monodromy matrix from the variational equations is
# good to about 1e-9 of its size, and so is psi (the curve's parameters to about 1e-9)
PSI_NOISE = 100.0


@dataclass(frozen=True)
class CurvePoint(BranchPoint):
    """A point of a two-parameter curve: ``param`` is mu1, ``param2`` mu2."""

    param2: float


@dataclass
class Curve(Branch):
    """A curve of folds or flips (``kind``) in (``param``, ``param2``)."""

    param2: str = ""
    kind: str = ""

    @property
    def params2(self) -> np.ndarray:
        return np.array([p.param2 for p in self.points])


class CurveContinuation(Continuation):
    """The curve of ``kind`` points of ``problem``'s orbits (parameter mu1 =
    ``problem.param``) over ``param2`` from ``mu2_0`` toward ``mu2_1``, mu1 kept in
    ``mu1_range``."""

    def __init__(
        self,
        problem: OrbitProblem,
        kind: str,
        param2: str,
        mu2_0: float,
        mu2_1: float,
        mu1_range: tuple[float, float],
        **options: Any,
    ) -> None:
        if kind not in CURVE_KINDS:
            raise AnalysisError(f"--curve {kind!r}: one of {', '.join(CURVE_KINDS)}")
        if param2 == problem.param:
            raise AnalysisError(f"--param2 {param2}: the same parameter as --param")
        super().__init__(problem, mu2_0, mu2_1, locate_grazing=False, **options)
        self.kind, self.param2 = kind, param2
        self.lo1, self.hi1 = sorted(float(v) for v in mu1_range)
        self.s1 = self.hi1 - self.lo1
        self.scale = np.concatenate((problem.scale, [self.s1, self.mu_scale]))
        self._problems: dict[float, OrbitProblem] = {}
        self.psi_scale = PSI_NOISE

    def problem_at(self, mu2: float) -> OrbitProblem:
        """The one-parameter problem at ``param2 = mu2`` (validated)."""
        mu2 = float(mu2)
        if mu2 not in self._problems:
            base = self.problem
            try:
                scenario = base.scenario.with_params({self.param2: mu2})
            except ScenarioError as exc:
                raise ScenarioError(f"--param2 {self.param2} = {mu2:g}: {exc}") from None
            if len(self._problems) > 64:
                self._problems.clear()
            self._problems[mu2] = OrbitProblem(
                scenario, base.param, base.period, mode=base.mode, rtol=base.rtol,
                max_events=base.max_events, mu_scale=self.s1,
            )  # fmt: skip
        return self._problems[mu2]

    def psi(self, monodromy: np.ndarray) -> float:
        """The test function: ``det(M - I)`` for a fold, ``det(M + I)`` for a flip."""
        sign = -1.0 if self.kind == "fold" else 1.0
        return float(np.linalg.det(monodromy + sign * np.eye(monodromy.shape[0])))

    def _psi_at(self, y: np.ndarray, mu1: float, mu2: float) -> float:
        lin = self.problem_at(mu2).linearize(y, mu1, with_param=False)
        return self.psi(lin.monodromy)

    def evaluate(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, Linearization]:
        z = u * self.scale
        y, mu1, mu2 = z[:-2], float(z[-2]), float(z[-1])
        pb = self.problem_at(mu2)
        lin = pb.linearize(y, mu1)
        h2 = MU_STEP * max(abs(mu2), self.mu_scale)
        up, m_up = self.problem_at(mu2 + h2).image(y, mu1)
        down, m_down = self.problem_at(mu2 - h2).image(y, mu1)
        if not (lin.smooth and m_up == lin.impacts and m_down == lin.impacts):
            raise MapError("the orbit is at grazing: its map is not smooth")
        g_mu2 = (up - down) / (2.0 * h2)
        psi = self.psi(lin.monodromy)
        s = pb.scale
        d_psi = np.empty(y.size + 2)
        for j in range(y.size):
            e = np.zeros(y.size)
            e[j] = STATE_STEP * s[j]
            d_psi[j] = (self._psi_at(y + e, mu1, mu2) - self._psi_at(y - e, mu1, mu2)) / (
                2.0 * STATE_STEP
            )  # per state scale
        h1 = MU_STEP * max(abs(mu1), self.s1)
        d_psi[-2] = (
            (self._psi_at(y, mu1 + h1, mu2) - self._psi_at(y, mu1 - h1, mu2)) / (2.0 * h1) * self.s1
        )
        d_psi[-1] = (
            (self._psi_at(y, mu1, mu2 + h2) - self._psi_at(y, mu1, mu2 - h2))
            / (2.0 * h2)
            * self.mu_scale
        )
        rows = np.column_stack((
            lin.d_state * s[None, :] / s[:, None],
            lin.d_param * self.s1 / s,
            g_mu2 * self.mu_scale / s,
        ))  # fmt: skip
        jac = np.vstack((rows, d_psi / self.psi_scale))
        residual = np.append(lin.residual / s, psi / self.psi_scale)
        return residual, jac, lin

    def outside(self, u: np.ndarray) -> str:
        mu1 = float(u[-2] * self.scale[-2])
        if not (self.lo1 <= mu1 <= self.hi1):
            return f"{self.problem.param} left its range [{self.lo1:g}, {self.hi1:g}]"
        return ""

    def new_branch(self) -> Curve:
        pb = self.problem
        return Curve(pb.scenario.name, pb.param, pb.period, pb.state_names, source=self,
                     param2=self.param2, kind=self.kind)  # fmt: skip

    def _branch_point(self, pt: _Point) -> CurvePoint:
        z = pt.u * self.scale
        lam = multipliers_of(pt.lin.monodromy)
        return CurvePoint(float(z[-2]), z[:-2], lam, pt.lin.impacts, pt.residual,
                          pt.iterations, float(z[-1]))  # fmt: skip

    def _accept(self, branch: Any, cur: Any, t: Any, nxt: _Point, tests: Any,
                t_new: Any = None) -> Any:  # fmt: skip
        """A curve's points only: its own degenerate points are not sought."""
        branch.points.append(self._branch_point(nxt))
        return tests

    def run_from(self, point: SpecialPoint, mu2: float, progress: Any = None) -> Curve:
        """The curve through ``point`` (located at ``param2 = mu2``)."""
        if point.kind != self.kind:
            raise AnalysisError(f"--curve {self.kind}: the start is a {point.kind}")
        self.psi_scale = PSI_NOISE * max(1.0, float(np.prod(1.0 + np.abs(point.multipliers))))
        u0 = np.concatenate((point.state, [point.param, mu2])) / self.scale
        e = np.zeros(u0.size)
        e[-1] = 1.0
        start = self.correct(u0, e)  # on the curve at mu2
        if start is None:
            raise AnalysisError(
                f"the {self.kind} at {self.problem.param} = {point.param:.10g} did not "
                f"converge on the extended system at {self.param2} = {mu2:g}"
            )
        curve = self.new_branch()
        return self.march(curve, start, self.tangent(start.jac, None), progress)


def bifurcation_curve(
    branch: Branch,
    kind: str,
    param2: str,
    stop2: float,
    *,
    start2: float | None = None,
    param_range: tuple[float, float] | None = None,
    which: int = 0,
    progress: Any = None,
    **options: Any,
) -> Curve:
    """The curve of ``branch``'s ``which``-th special point of ``kind`` in (the branch's
    parameter, ``param2``), from ``param2``'s value in the scenario (or ``start2``)
    toward ``stop2``; the branch's parameter kept in ``param_range`` (default: the
    branch's range).  Options as :class:`.continuation.Continuation`'s."""
    cont = branch.source
    if not isinstance(cont, Continuation):
        raise AnalysisError("the branch does not say how it was continued (branch.source)")
    points = branch.special_of(kind)
    if not (0 <= which < len(points)):
        raise AnalysisError(
            f"--curve {kind}: the branch has {len(points)} {kind} point(s), not a number {which}"
        )
    problem = cont.problem
    if start2 is None:
        start2 = OrbitProblem(problem.scenario, param2, problem.period).value()
    lo, hi = param_range if param_range is not None else (cont.lo, cont.hi)
    opts = {"step": cont.ds, "max_step": cont.max_step, "min_step": cont.min_step,
            "max_points": cont.max_points, **options}  # fmt: skip
    cc = CurveContinuation(problem, kind, param2, float(start2), float(stop2), (lo, hi), **opts)
    return cc.run_from(points[which], float(start2), progress)
