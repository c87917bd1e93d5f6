"""What kind of steady motion a sequence of stroboscopic points is: n-m or not periodic.

A motion is *n-m* when its stroboscopic points repeat after ``n`` forcing
periods and it has ``m`` impacts (or contact onsets) in those ``n`` periods,
the book's label (1-1: one impact per period; 2-1: period two, one impact
every two periods).  Points are compared in units of each state's scale
(the clearance for displacements, clearance times frequency for velocities):
two points are the same when every component differs by less than ``tol``
scales.  When no period up to ``max_period`` fits, the motion is reported as
``"chaotic or quasi-periodic"`` with its number of distinct points; the
points alone do not tell those two apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_TOL = 1e-6  # in state scales
DEFAULT_MAX_PERIOD = 32
NOT_PERIODIC = "chaotic or quasi-periodic"


@dataclass(frozen=True)
class Motion:
    """A classified motion: ``period`` n (0 when not periodic), ``impacts`` m over those n
    periods (over one period on average when not periodic), and the distinct points."""

    period: int
    impacts: int | float
    distinct: int
    label: str

    @property
    def periodic(self) -> bool:
        return self.period > 0


def distinct_count(points: np.ndarray, scale: np.ndarray, tol: float = DEFAULT_TOL) -> int:
    """How many points differ from every earlier kept point by more than ``tol`` scales
    in some component (greedy clustering, in order)."""
    z = np.atleast_2d(np.asarray(points, dtype=float) / np.asarray(scale, dtype=float))
    reps = np.empty((0, z.shape[1]))
    for row in z:
        if not np.any(np.all(np.abs(reps - row) <= tol, axis=1)):
            reps = np.vstack((reps, row))
    return reps.shape[0]


def classify(
    points: np.ndarray,
    impacts: np.ndarray,
    scale: np.ndarray,
    tol: float = DEFAULT_TOL,
    max_period: int = DEFAULT_MAX_PERIOD,
) -> Motion:
    """Classify steady stroboscopic points (transients already discarded).

    ``points[k]`` ends period k, ``impacts[k]`` counts that period's impacts.
    Periodicity needs at least two repetitions of the pattern in ``points``.
    """
    z = np.asarray(points, dtype=float) / np.asarray(scale, dtype=float)
    imp = np.asarray(impacts)
    if z.ndim != 2 or z.shape[0] != imp.shape[0] or z.shape[0] < 2:
        raise ValueError("points must be a (K, n) array with K >= 2 matching impacts (K,)")
    if not (tol > 0.0 and max_period >= 1):
        raise ValueError("tol must be > 0 and max_period >= 1")
    if not np.all(np.isfinite(z)):
        raise ValueError("points are not finite")
    K = z.shape[0]
    for n in range(1, min(max_period, K // 2) + 1):
        if np.all(np.abs(z[n:] - z[:-n]) <= tol):
            m = int(imp[-n:].sum())
            return Motion(n, m, n, f"{n}-{m}")
    return Motion(0, float(imp.mean()), distinct_count(points, scale, tol), NOT_PERIODIC)
