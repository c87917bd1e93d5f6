"""Special points of a branch of periodic orbits: test functions and their location.

Between two points of a branch (:mod:`.continuation`) a test function that changes sign
marks a special point, located by Brent's method on the arclength from the first point
(each trial point corrected onto the branch):

* ``fold``: the parameter turns, ``dmu/ds`` (the tangent's last component) through zero;
  a multiplier passes through +1 there (a saddle-node of orbits);
* ``branch-point``: ``det(dG/dy) = prod(lambda - 1)`` through zero where the parameter
  does not turn (another branch crosses: a symmetry-breaking or transcritical point);
* ``flip``: ``prod(lambda + 1)`` through zero, a multiplier through -1 (period doubling);
* ``neimark-sacker``: ``prod_{i<j}(lambda_i lambda_j - 1)`` through zero with the pair
  at the zero complex (a pair through the unit circle); a real pair with product 1 (a
  neutral saddle) is not a bifurcation and is not reported.

A branch point is where two branches cross: there the corrector's matrix is singular,
so it is located less precisely than the others (to about 1e-7 of the parameter's range
on Feng & Yang's symmetric orbit); a point whose location stopped short says so
(``details["located"] = False``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import brentq

from .floquet import multipliers_of

KINDS = ("fold", "branch-point", "flip", "neimark-sacker")
LOCATE_XTOL = 1e-12  # scaled arclength
_COMPLEX = 1e-8  # a pair counts as complex above this imaginary part (relative)


@dataclass(frozen=True)
class SpecialPoint:
    """A special point located on a branch, between points ``index`` and ``index + 1``:
    its ``kind`` (:data:`KINDS`, or ``"grazing"``), parameter, state on the section,
    multipliers (largest modulus first), Newton's residual (state scales), the critical
    multiplier, and ``details`` of its kind (a grazing's square-root law)."""

    kind: str
    index: int
    param: float
    state: np.ndarray
    multipliers: np.ndarray
    residual: float
    critical: complex
    details: dict[str, Any] = field(default_factory=dict)

    def report(self) -> dict[str, Any]:
        """JSON-able: kind, parameter, state, multipliers as [re, im], residual."""
        return {
            "kind": self.kind,
            "between_points": [self.index, self.index + 1],
            "param": self.param,
            "state": [float(v) for v in self.state],
            "multipliers": [[float(z.real), float(z.imag)] for z in self.multipliers],
            "critical_multiplier": [float(self.critical.real), float(self.critical.imag)],
            "residual": self.residual,
            **self.details,
        }


def _pair_products(lam: np.ndarray) -> np.ndarray:
    i, j = np.triu_indices(lam.size, 1)
    return lam[i] * lam[j]


def test_values(lam: np.ndarray, jacobian: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """The test functions at a point, in :data:`KINDS` order: ``dmu/ds``,
    ``prod(lambda - 1)``, ``prod(lambda + 1)``, ``prod(lambda_i lambda_j - 1)``."""
    fold = float(tangent[-1])
    det = float(np.prod(lam - 1.0).real)
    flip = float(np.prod(lam + 1.0).real)
    pairs = _pair_products(lam)
    ns = float(np.prod(pairs - 1.0).real) if pairs.size else 1.0
    return np.array([fold, det, flip, ns])


def _critical(kind: str, lam: np.ndarray) -> complex:
    """The multiplier (or, for a pair, the one of positive imaginary part) at the test's
    zero."""
    if kind in ("fold", "branch-point"):
        return complex(lam[np.argmin(np.abs(lam - 1.0))])
    if kind == "flip":
        return complex(lam[np.argmin(np.abs(lam + 1.0))])
    i, j = np.triu_indices(lam.size, 1)
    k = int(np.argmin(np.abs(lam[i] * lam[j] - 1.0)))
    a = lam[i[k]]
    return complex(a if a.imag >= 0 else lam[j[k]])


def locate_between(
    cont: Any,
    cur: Any,
    t: np.ndarray,
    nxt: Any,
    before: np.ndarray,
    after: np.ndarray,
    index: int,
) -> list[SpecialPoint]:
    """The special points between the converged points ``cur`` and ``nxt`` (the step
    from ``cur`` along ``t``), whose test functions are ``before`` and ``after``."""
    changed = [k for k in range(len(KINDS)) if before[k] * after[k] < 0.0]
    if 0 in changed and 1 in changed:
        changed.remove(1)  # the fold's det(dG/dy) zero: not another branch
    found = []
    s_end = float(t @ (nxt.u - cur.u))
    for k in changed:
        point = _locate(cont, cur, t, s_end, k)
        if point is None:
            continue
        pt, lam, located = point
        kind = KINDS[k]
        crit = _critical(kind, lam)
        if kind == "neimark-sacker" and abs(crit.imag) <= _COMPLEX * max(abs(crit), 1.0):
            continue  # a neutral saddle
        y, mu = cont._split(pt.u)
        details = {} if located else {"located": False}
        found.append(SpecialPoint(kind, index, mu, y, lam, pt.residual, crit, details))
    return found


def _locate(cont: Any, cur: Any, t: np.ndarray, s_end: float, k: int) -> Any:
    """The corrected point where test ``k`` vanishes, its multipliers, and whether it
    was located to :data:`LOCATE_XTOL`.  Near a branch point the corrector's matrix is
    singular and a trial point may not converge: then the converged trial point with the
    smallest test value stands for it (not located).  None when the test has one sign
    at the ends after all."""
    memo: dict[float, Any] = {}

    def at(s: float) -> Any:
        if s not in memo:
            pt = cont.correct(cur.u + s * t, t)
            if pt is None:
                raise _NoPointError
            lam = multipliers_of(pt.lin.monodromy)
            tangent = cont.tangent(pt.jac, t)
            memo[s] = (pt, lam, test_values(lam, pt.jac, tangent)[k])
        return memo[s]

    try:
        lo, hi = at(0.0)[2], at(s_end)[2]
    except _NoPointError:
        return None
    if lo * hi > 0.0:
        return None
    try:
        s = brentq(lambda s: at(s)[2], 0.0, s_end, xtol=LOCATE_XTOL, rtol=4 * np.finfo(float).eps)
        pt, lam, _ = at(s)
        return pt, lam, True
    except _NoPointError:
        best = min(memo.values(), key=lambda m: abs(m[2]))
        return best[0], best[1], False


class _NoPointError(Exception):
    """A trial point of a location did not converge."""
