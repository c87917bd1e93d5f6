"""Grazing at the end of a continued branch: where a non-impacting orbit first touches
its rigid obstacle.

The corrector stops where the impacts per n periods change (the map is not smooth
there, :mod:`.continuation`).  When the branch is a non-impacting period-1 orbit and the
obstacle rigid, the grazing is located where the free orbit's minimum gap is zero and
the square-root law of the map is fitted there (:mod:`.grazing`); otherwise the special
point is the bracket the corrector left, not located further.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .bifurcation_points import SpecialPoint
from .errors import AnalysisError
from .grazing import expected_exponent, locate, sqrt_law
from .orbit_problem import MU_STEP

WIDEN = 8  # times the bracket is doubled when the free orbit's gap keeps its sign


def branch_grazing(cont: Any, branch: Any) -> SpecialPoint | None:
    """The grazing where ``branch`` (continued by ``cont``) stopped, or None when it
    did not stop at an impacts change."""
    if getattr(cont, "rejected", None) is None or not branch.points:
        return None
    last = branch.points[-1]
    mu_try, tried = cont.rejected
    # the orbit the corrector last found, if its impacts differ (else: orbits nearby do)
    after = None if tried is None or tried.lin.impacts == last.impacts else tried.lin.impacts
    details: dict[str, Any] = {"impacts_before": last.impacts, "impacts_after": after}
    problem = cont.problem
    lo, hi = last.param, float(mu_try)
    if hi == lo:
        return None
    # the difference images in the parameter see grazing from MU_STEP away: reach past it
    reach = 4.0 * MU_STEP * max(abs(lo), problem.mu_scale)
    hi = lo + math.copysign(max(abs(hi - lo), reach), hi - lo)
    if last.impacts == 0 and problem.period == 1:
        located = _located(problem, lo, hi, last.state)
        if located is not None:
            value, state, vn = located
            details["normal_velocity_relative"] = vn
            try:
                depths, devs, slope = sqrt_law(problem.scenario, problem.param, value, state)
                details["sqrt_law"] = {
                    "depths": depths.tolist(),
                    "deviations": devs.tolist(),
                    "exponent": slope,
                    "expected": expected_exponent(problem.system(value)),
                }
            except AnalysisError as exc:
                details["sqrt_law"] = {"error": str(exc)}
            details["located"] = True
            return SpecialPoint("grazing", len(branch.points) - 1, value, state,
                                last.multipliers, 0.0, complex(np.nan), details)  # fmt: skip
    details["located"] = False
    details["bracket"] = sorted((lo, hi))
    return SpecialPoint("grazing", len(branch.points) - 1, hi, last.state,
                        last.multipliers, last.residual, complex(np.nan), details)  # fmt: skip


def _located(problem: Any, lo: float, hi: float, guess: np.ndarray) -> Any:
    """:func:`.grazing.locate` on ``[lo, hi]``, the bracket doubled while the free
    orbit's gap keeps its sign (the corrector's last try may stop short of grazing)."""
    for _ in range(WIDEN + 1):
        try:
            return locate(problem.scenario, problem.param, min(lo, hi), max(lo, hi),
                          guess=guess)  # fmt: skip
        except AnalysisError:
            hi = lo + 2.0 * (hi - lo)
    return None
