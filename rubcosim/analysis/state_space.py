"""Verified attractor neighbourhoods as balls in the full state space.

Used by the slice method (every sample followed in the full state) and by the
pursuit method on a 2-D section: a cell-sized neighbourhood, verified from its
centre only, can straddle a basin boundary on a coarse grid (Feng & Yang's
1-1 orbit lies within a few cells of the boundary of the 1-0 orbit P3's basin),
so its size is set in state scales, not cells, and tested in more directions.
"""

from __future__ import annotations

import concurrent.futures as cf
from typing import Any

import numba as nb
import numpy as np

from .attractors import CHAOS_KEEP, MATCH_TOL, Attractor, converges_to, largest_exponent
from .cellmap import Grid, same_motion
from .maps import StroboscopicMap

RADII = (0.05, 0.01, 2e-3)  # state scales: ball radii tried around a periodic attractor
CHAOS_SPACING = 3.0  # a non-periodic attractor's ball: this many median point spacings


def test_steps(scale: np.ndarray, axes: list[int]) -> np.ndarray:
    """Offsets of unit max-norm (in state scales, state units) at which a ball's radius
    is tested: +- every state axis, and the four diagonals of the plane ``axes``."""
    n = scale.size
    steps = [np.diag(scale), -np.diag(scale)]
    a, b = axes
    for sa, sb in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        d = np.zeros(n)
        d[a], d[b] = sa * scale[a], sb * scale[b]
        steps.append(d[None, :])
    return np.vstack(steps)


@nb.njit(cache=True, parallel=True)
def within_radius(z, pts, radius, hit):  # pragma: no cover - compiled
    """``hit[i]``: whether row i of ``z`` lies within ``radius`` (max norm) of a row of
    ``pts`` (sorted by their first column); False for a row that is not finite.  Only
    the points whose first coordinate is within the radius are compared (a binary
    search finds them; the window is widened by a part in 1e12 so that rounding of its
    ends cannot drop one), so many points cost a logarithm, not a pass."""
    first = pts[:, 0]
    pad = radius * (1.0 + 1e-12)
    for i in nb.prange(z.shape[0]):
        row = z[i]
        if not np.all(np.isfinite(row)):
            continue
        j = np.searchsorted(first, row[0] - pad)
        while j < pts.shape[0] and first[j] <= row[0] + pad:
            d = 0.0
            for c in range(row.shape[0]):
                d = max(d, abs(row[c] - pts[j, c]))
            if d <= radius:
                hit[i] = True
                break
            j += 1


@nb.njit(cache=True)
def nearest_spacings(pts):  # pragma: no cover - compiled
    """Each point's distance (max norm) to its nearest other point, for ``pts`` sorted
    by their first column: a sweep outwards from each point that stops where the first
    coordinate alone is farther than the nearest found."""
    n = pts.shape[0]
    out = np.full(n, np.inf)
    for i in range(n):
        best = np.inf
        for step in (-1, 1):
            j = i + step
            while 0 <= j < n and abs(pts[j, 0] - pts[i, 0]) <= best:
                d = 0.0
                for c in range(pts.shape[1]):
                    d = max(d, abs(pts[j, c] - pts[i, c]))
                best = min(best, d)
                j += step
        out[i] = best
    return out


class StateSpace:
    """Verified neighbourhoods in the full state space: a ball of radius
    ``Attractor.radius`` (state scales, max norm) around each of its points."""

    def __init__(
        self,
        smap: StroboscopicMap,
        grid: Grid,
        axes: tuple[int, int],
        pool: cf.Executor | None = None,
    ) -> None:
        """``pool``: where a non-periodic attractor's Lyapunov exponent is computed while
        the analysis goes on (:meth:`lyapunov_done` collects them); without it, at once."""
        self.scale = smap.scale
        self.grid = grid
        self.axes = list(axes)
        self.pool = pool
        self._points: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # by id(attractor.points)

    def _sorted(self, a: Attractor) -> np.ndarray:
        """The attractor's points in state scales, sorted by the first state, built once."""
        key = id(a.points)
        if key not in self._points or self._points[key][0] is not a.points:
            z = a.points / self.scale
            self._points[key] = (a.points, np.ascontiguousarray(z[np.argsort(z[:, 0])]))
        return self._points[key][1]

    def _near(self, states: np.ndarray, a: Attractor) -> np.ndarray:
        return self._near_scaled(states / self.scale, a)

    def _near_scaled(self, z: np.ndarray, a: Attractor) -> np.ndarray:
        """Whether each state (``z``: in state scales) lies within ``a``'s radius of one
        of its points (max norm); False for a state that is not finite."""
        hit = np.zeros(z.shape[0], dtype=bool)
        within_radius(np.ascontiguousarray(z), self._sorted(a), float(a.radius), hit)
        return hit

    @staticmethod
    def lyapunov_done(known: list[Attractor]) -> None:
        """Wait for the Lyapunov exponents computed on the pool; each ``motion`` then
        holds its number (1/s), or why it could not be measured."""
        for a in known:
            value = a.motion.get("lyapunov")
            if isinstance(value, cf.Future):
                a.motion["lyapunov"] = value.result()

    def locate(self, states: np.ndarray, known: list[Attractor]) -> np.ndarray:
        """Per state: the first attractor whose ball holds it, else -1."""
        out = np.full(states.shape[0], -1, dtype=np.int64)
        z = states / self.scale
        for k in range(len(known) - 1, -1, -1):
            out[self._near_scaled(z, known[k])] = k
        return out

    def match(self, smap: StroboscopicMap, motion: dict[str, Any], known: list[Attractor]) -> int:
        """Index of the known attractor the simulated ``motion`` is on, else -1."""
        pts = np.asarray(motion["poincare_points"])
        for k, a in enumerate(known):
            if a.periodic and same_motion(a.motion, motion, smap.scale, MATCH_TOL):
                return k
            if not a.periodic and not motion.get("periodic") and np.any(self._near(pts, a)):
                return k
        return -1

    def build(self, smap: StroboscopicMap, motion: dict[str, Any], orbit: Any) -> Attractor:
        """A new attractor and its verified radius: for a periodic one the largest of
        ``RADII`` whose test points (each point +- the radius along every state axis,
        and along the four diagonals of the grid's plane) all converge to it, else
        ``MATCH_TOL``; for a non-periodic one ``CHAOS_SPACING``
        median spacings of its ``CHAOS_KEEP`` orbit points."""
        if motion["periodic"]:
            pts = np.asarray(motion["poincare_points"])
            radius = MATCH_TOL
            steps = test_steps(self.scale, self.axes)
            for r in RADII:
                tests = (pts[:, None, :] + r * steps[None, :, :]).reshape(-1, pts.shape[1])
                if np.all(converges_to(smap, tests, pts, motion["period"])):
                    radius = r
                    break
        else:
            more = smap.orbit(orbit.final_state, keep=CHAOS_KEEP)
            pts = more.points if more.ok else orbit.points
            z = pts / self.scale
            z = np.ascontiguousarray(z[np.argsort(z[:, 0])])
            radius = CHAOS_SPACING * float(np.median(nearest_spacings(z)))
            motion["section_points"] = pts[-256:].tolist()
            last = more if more.ok else orbit
            if self.pool is None:
                motion["lyapunov"] = largest_exponent(smap, last)
            else:  # only reported (no label depends on it): on a worker, meanwhile
                motion["lyapunov"] = self.pool.submit(largest_exponent, smap, last)
        motion["slice_points"] = np.asarray(motion["poincare_points"])[:, self.axes].tolist()
        cells = np.unique(self.grid.cell_of(pts[:, self.axes]))
        cells = cells[cells != self.grid.sink]
        near = np.zeros(self.grid.n_cells, dtype=bool)
        return Attractor(motion, pts, cells, near, radius)
