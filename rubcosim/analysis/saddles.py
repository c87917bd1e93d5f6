"""Fixed points of the stroboscopic map found from the samples, refined by Newton.

Every sample's one-period displacement ``|P(y) - y|`` (in state scales, the
largest component) is known from the mapping.  Near a fixed point of P it
goes to zero whatever the fixed point's stability, so the cells where the
smallest displacement of their samples is smallest (taken at least ``SPREAD``
cells apart) and below ``WIDTHS`` cell widths are the candidates (a strongly
unstable saddle moves its cell's samples by several widths).  Newton's method
on ``P(y) - y`` from each candidate's best sample (:func:`.floquet.floquet`,
at the tight tolerance ``FLOQUET_RTOL``) refines it and gives the
multipliers.  Newton also starts from every corner of the cell grid around
which the cells' mean displacement winds once (a nonzero index: a fixed
point inside, by degree theory, where the map is continuous; a grazing curve
can fake one, and Newton then finds nothing).  A fixed point with exactly
one multiplier outside the unit
circle is a *saddle* (its stable manifold is a basin boundary of a planar
map); stable ones cross-check the periodic attractors.
"""

from __future__ import annotations

import concurrent.futures as cf
from functools import partial
from typing import Any

import numpy as np

from .cellmap import Grid
from .errors import MapError
from .floquet import FLOQUET_RTOL, Floquet, floquet, floquet_report
from .maps import StroboscopicMap
from .parallel import gather_interleaved, submit_interleaved

MAX_CANDIDATES = 64  # Newton starts, smallest displacement first
SPREAD = 1  # cells between Newton starts
WIDTHS = 4.0  # candidate cells: smallest displacement below this many cell widths
SAME_POINT = 1e-6  # state scales: Newton results this close are one fixed point
NEWTON_TOL = 1e-10
NEWTON_ITER = 10  # from a start this close Newton converges in a few; else give up


def winding_starts(
    grid: Grid, points: np.ndarray, images: np.ndarray, scale: np.ndarray, samples: int
) -> np.ndarray:
    """Corners of the cell grid around which the mean displacement field of the cells
    winds (index != 0: a fixed point inside the 2 x 2 block of cell centres, whatever
    its stability, when the field is continuous there), most compact block first."""
    with np.errstate(invalid="ignore"):
        disp = np.nanmean(((images - points) / scale).reshape(grid.n_cells, samples, 2), axis=1)
    ang = np.arctan2(disp[:, 1], disp[:, 0]).reshape(grid.nv, grid.nx)
    corners = [ang[:-1, :-1], ang[:-1, 1:], ang[1:, 1:], ang[1:, :-1]]
    turn = np.zeros_like(corners[0])
    for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
        turn += np.angle(np.exp(1j * (b - a)))  # each step wrapped to (-pi, pi]
    with np.errstate(invalid="ignore"):
        j, i = np.nonzero(np.abs(turn) > np.pi)  # a whole turn: index +1 or -1
    size = np.hypot(disp[:, 0], disp[:, 1]).reshape(grid.nv, grid.nx)
    order = np.argsort(size[j, i] + size[j + 1, i + 1], kind="stable")
    j, i = j[order], i[order]
    return np.column_stack((grid.x0 + (i + 1) * grid.dx, grid.v0 + (j + 1) * grid.dv))


def fixed_point_candidates(
    grid: Grid,
    points: np.ndarray,
    images: np.ndarray,
    scale: np.ndarray,
    samples: int,
    where: np.ndarray | None = None,
) -> np.ndarray:
    """Sample points (rows) from which to start Newton, smallest displacement first,
    in the cells where ``where`` (bool per cell) holds, default all."""
    with np.errstate(invalid="ignore"):
        d = np.max(np.abs(images - points) / scale, axis=1)
    d[~np.isfinite(d)] = np.inf
    per_cell = d.reshape(grid.n_cells, samples)
    best = np.argmin(per_cell, axis=1)
    dmin = per_cell[np.arange(grid.n_cells), best]
    width = WIDTHS * max(grid.dx / scale[0], grid.dv / scale[1])
    # smallest first, at least SPREAD cells apart: a saddle's cell need not be a local
    # minimum (its stable direction is a valley of small displacements)
    ok = dmin < width if where is None else (dmin < width) & where
    order = np.flatnonzero(ok)
    order = order[np.argsort(dmin[order], kind="stable")]
    kept: list[int] = []
    for c in order:
        i, j = c % grid.nx, c // grid.nx
        if all(max(abs(i - k % grid.nx), abs(j - k // grid.nx)) > SPREAD for k in kept):
            kept.append(int(c))
            if len(kept) == MAX_CANDIDATES:
                break
    cand = np.array(kept, dtype=np.int64)
    return points[cand * samples + best[cand]]


def newton_box(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Where Newton's iterates may go: the region widened by its own size on each side
    (only fixed points inside the region are kept; an iterate far outside has diverged)."""
    w, h = grid.x1 - grid.x0, grid.v1 - grid.v0
    return np.array([grid.x0 - w, grid.v0 - h]), np.array([grid.x1 + w, grid.v1 + h])


def _newton(
    tight: StroboscopicMap, starts: np.ndarray, box: tuple[np.ndarray, np.ndarray] | None = None
) -> list[Floquet | None]:
    """Newton from each start (one task): the fixed point and its multipliers, or None
    where Newton stops on grazing, a singular step or an iterate outside ``box``."""
    out: list[Floquet | None] = []
    for y in starts:
        try:
            out.append(floquet(tight, y, 1, tol=NEWTON_TOL, max_iter=NEWTON_ITER, box=box))
        except (MapError, np.linalg.LinAlgError):
            out.append(None)  # grazing, a singular step, diverged: no fixed point from here
    return out


class FixedPointSearch:
    """Newton from the samples' candidate starts (see the module doc), in two parts so
    that the first runs while an analysis does other work: the winding starts, which
    need only the samples and their images, are submitted to ``pool`` at once; the
    smallest-displacement starts once the cells to search are known (:meth:`result`).
    The result does not depend on where the starts run (processes, a Dask cluster,
    inline)."""

    def __init__(
        self,
        smap: StroboscopicMap,
        grid: Grid,
        points: np.ndarray,
        images: np.ndarray,
        samples: int,
        pool: cf.Executor,
        parts: int,
    ) -> None:
        self.smap, self.grid, self.samples = smap, grid, samples
        self.points, self.images = points, images
        self.pool, self.parts = pool, parts
        self.tight = StroboscopicMap(smap.system, FLOQUET_RTOL, smap.max_events)
        wind = winding_starts(grid, points, images, smap.scale, samples)[:MAX_CANDIDATES]
        self._wind = self._submit(wind)

    def _submit(self, starts: np.ndarray) -> tuple[list[cf.Future], int]:
        n = min(self.parts, max(1, starts.shape[0]))
        newton = partial(_newton, box=newton_box(self.grid))
        return submit_interleaved(self.pool, n, newton, self.tight, starts), starts.shape[0]

    @staticmethod
    def _gather(submitted: tuple[list[cf.Future], int]) -> list[Floquet | None]:
        parts, count = submitted
        return gather_interleaved(parts, [None] * count)

    def result(self, where: np.ndarray | None = None) -> list[dict[str, Any]]:
        """The distinct fixed points of P found from the winding starts and the cells
        where ``where`` holds (the boundary and attractor cells: a saddle on a basin
        boundary lies in a mixed cell): state, cell (0-based ``c = j nx + i``), impacts
        per period, multipliers and whether it is a saddle, in Newton's start order."""
        small = fixed_point_candidates(
            self.grid, self.points, self.images, self.smap.scale, self.samples, where
        )
        newton = self._gather(self._wind) + self._gather(self._submit(small))
        return _distinct(self.smap, self.grid, newton)


def _distinct(
    smap: StroboscopicMap, grid: Grid, newton: list[Floquet | None]
) -> list[dict[str, Any]]:
    """The distinct converged fixed points inside the region among Newton's results, in
    their order, with their cell, impacts, multipliers and whether each is a saddle."""
    found: list[dict[str, Any]] = []
    for f in newton:
        if f is None:
            continue
        cell = int(grid.cell_of(f.state[None, :])[0])
        if f.residual > 1e3 * NEWTON_TOL or cell == grid.sink:
            continue
        if any(np.all(np.abs(f.state - p["state"]) / smap.scale <= SAME_POINT) for p in found):
            continue
        outside = int(np.sum(np.abs(f.multipliers) > 1.0))
        found.append(
            {
                "state": f.state,
                "cell": cell,
                "impacts": f.impacts,
                "outside_unit_circle": outside,
                "saddle": outside == 1,
                **floquet_report(f),
            }
        )
    return found
