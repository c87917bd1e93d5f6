"""Basins of attraction by generalized cell mapping (Hsu; as Feng & Yang use it).

The stroboscopic section (x, x') of a single-DOF system is divided into
``nx * nv`` cells over ``region = (x0, x1, v0, v1)``.  Cell numbering: the cell
with x index ``i`` (0 ... nx-1, from x0) and x' index ``j`` (0 ... nv-1, from
v0) is number ``c = j * nx + i``; its centre is ``(x0 + (i + 1/2) dx,
v0 + (j + 1/2) dv)``.  Number ``nx * nv`` is the *sink*: everything that
leaves the region, fails to integrate, or starts inside an obstacle (a
point beyond a rigid stop is not a state of the system).

``samples`` random points per cell (uniform in the cell, from ``seed``) are
mapped one forcing period by the event-switching ``fast`` engine; the share
of a cell's points landing in each cell gives the cell-to-cell transition
probabilities.  On that graph:

- *persistent groups* (closed communicating classes: strongly connected and
  with no way out) are the attractors; the sink is one too, not counted;
- every other cell is *transient*; the attractors it can reach (with
  positive probability) decide where it belongs: the *basin* of attractor k
  is the set of cells that reach k and no other attractor (the attractor's
  own cells included); *boundary* cells reach two or more; *escape* cells
  reach none (only the sink);
- *saddles*, where findable: transient strongly connected groups with a
  cycle, made of boundary cells only, the cell picture of the unstable sets
  on the basin boundaries.

Each attractor's period as a cell chain (gcd of its cycle lengths) is given,
and its motion is found by direct simulation from the centre of its most
visited cell: the n-m label and the stroboscopic points.  Coarse cells can
split one attractor into several persistent groups (a cell whose few
samples all stay inside it); groups whose simulated periodic motions
coincide (same n-m, points within ``MERGE_TOL`` state scales) are merged
into one attractor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .basin_metrics import metrics_of
from .errors import AnalysisError, MapError
from .maps import StroboscopicMap, admissible
from .motion import classify
from .parallel import map_in_chunks

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

DEFAULT_CHUNK = 2000  # cells per task
CELL_MAP_RTOL = 1e-7  # the map's tolerance: cells are far coarser than this
LABEL_BOUNDARY = -2
LABEL_ESCAPE = -1
MERGE_TOL = 1e-3  # state scales: simulated motions this close are the same attractor


@dataclass(frozen=True)
class Grid:
    """``nx * nv`` cells over ``x0 <= x < x1``, ``v0 <= x' < v1``."""

    nx: int
    nv: int
    x0: float
    x1: float
    v0: float
    v1: float

    def __post_init__(self) -> None:
        if not (isinstance(self.nx, int) and isinstance(self.nv, int) and self.nx >= 1):
            raise AnalysisError(f"--grid {self.nx}x{self.nv}: cell counts must be integers >= 1")
        if self.nv < 1:
            raise AnalysisError(f"--grid {self.nx}x{self.nv}: cell counts must be integers >= 1")
        vals = (self.x0, self.x1, self.v0, self.v1)
        if not all(math.isfinite(v) for v in vals) or self.x1 <= self.x0 or self.v1 <= self.v0:
            raise AnalysisError(
                f"--region {self.x0:g}:{self.x1:g},{self.v0:g}:{self.v1:g}: needs finite "
                "x0 < x1 and v0 < v1"
            )

    @classmethod
    def parse(cls, grid: str | tuple[int, int], region: str | tuple[float, ...]) -> Grid:
        """From ``"NXxNV"`` (or ``(nx, nv)``) cells over ``"X0:X1,V0:V1"`` (or
        ``(x0, x1, v0, v1)``, the state's units); errors quote ``--grid``/``--region``."""
        if isinstance(grid, str):
            try:
                nx, nv = (int(s) for s in grid.lower().split("x"))
            except ValueError:
                raise AnalysisError(f"--grid {grid!r}: expected NXxNV, e.g. 200x200") from None
            grid = (nx, nv)
        if isinstance(region, str):
            try:
                xs, vs = region.split(",")
                x0, x1 = (float(s) for s in xs.split(":"))
                v0, v1 = (float(s) for s in vs.split(":"))
            except ValueError:
                raise AnalysisError(
                    f"--region {region!r}: expected X0:X1,V0:V1, e.g. -3:1,-6:6"
                ) from None
            region = (x0, x1, v0, v1)
        if len(grid) != 2 or len(region) != 4:
            raise AnalysisError(
                f"--grid {grid!r} / --region {region!r}: (nx, nv), (x0, x1, v0, v1)"
            )
        return cls(*grid, *(float(v) for v in region))

    @property
    def n_cells(self) -> int:
        return self.nx * self.nv

    @property
    def sink(self) -> int:
        return self.n_cells

    @property
    def dx(self) -> float:
        return (self.x1 - self.x0) / self.nx

    @property
    def dv(self) -> float:
        return (self.v1 - self.v0) / self.nv

    def centres(self, cells: np.ndarray | None = None) -> np.ndarray:
        c = np.arange(self.n_cells) if cells is None else np.asarray(cells)
        i, j = c % self.nx, c // self.nx
        return np.column_stack((self.x0 + (i + 0.5) * self.dx, self.v0 + (j + 0.5) * self.dv))

    def cell_of(self, states: np.ndarray) -> np.ndarray:
        """Cell number of each (x, x') row; the sink for rows outside or not finite."""
        x, v = states[:, 0], states[:, 1]
        with np.errstate(invalid="ignore"):
            i = np.floor((x - self.x0) / self.dx)
            j = np.floor((v - self.v0) / self.dv)
            inside = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.nv)
        cells = np.full(states.shape[0], self.sink, dtype=np.int64)
        cells[inside] = (j[inside] * self.nx + i[inside]).astype(np.int64)
        return cells


def sample_cells(grid: Grid, first: int, last: int, samples: int, seed: int) -> np.ndarray:
    """``samples`` uniform random points in each of cells ``first .. last - 1``; the same
    points for the same (seed, first), whatever runs them."""
    rng = np.random.default_rng([seed, first])
    cells = np.repeat(np.arange(first, last), samples)
    u = rng.random((cells.size, 2))
    lo = grid.centres(cells) - 0.5 * np.array([grid.dx, grid.dv])
    return lo + u * np.array([grid.dx, grid.dv])


def all_samples(grid: Grid, samples: int, seed: int, chunk: int = DEFAULT_CHUNK) -> np.ndarray:
    """Every cell's sample points, in cell order, as the tasks of ``chunk`` cells draw
    them (:func:`sample_cells` per task: each task has its own random stream)."""
    starts = range(0, grid.n_cells, chunk)
    return np.concatenate(
        [sample_cells(grid, a, min(a + chunk, grid.n_cells), samples, seed) for a in starts]
    )


def map_cells(
    smap: StroboscopicMap, grid: Grid, first: int, last: int, samples: int, seed: int
) -> dict[str, np.ndarray]:
    """One task: the image cell of every sample of cells ``first .. last - 1`` (rows in
    cell order, ``samples`` per cell) and its impacts during the period."""
    states = sample_cells(grid, first, last, samples, seed)
    ok = admissible(smap, states)
    images, _, impacts, status = smap.map(states)
    cells = grid.cell_of(images)
    cells[(status != 0) | ~ok] = grid.sink
    return {"image": cells.astype(np.int32), "impacts": impacts.astype(np.int16)}


@dataclass
class Basins:
    """The outcome of a cell mapping; see the module docstring for the terms."""

    grid: Grid
    samples: int
    seed: int
    image: np.ndarray  # (n_cells, samples) image cell of each sample
    labels: np.ndarray  # per cell: basin k >= 0, LABEL_BOUNDARY, LABEL_ESCAPE
    attractor_of: np.ndarray  # per cell: attractor k whose persistent group holds it, else -1
    reach: np.ndarray  # (n_cells, n_attractors) bool: the cell reaches attractor k
    saddles: list[np.ndarray]  # cell numbers of each saddle group
    chain_periods: list[int]
    motions: list[dict[str, Any]] = field(default_factory=list)
    # what report.json states besides: parameters, state names, rtol, wall time (s)
    info: dict[str, Any] = field(default_factory=dict)
    method: str = "gcm"  # "gcm": generalized cell mapping; "pursuit": see .pursuit
    # per cell, the share of its samples going to each attractor and (last column) to
    # the sink; only the pursuit method has it
    shares: np.ndarray | None = None
    fixed_points: list[dict[str, Any]] = field(default_factory=list)  # Newton's (pursuit)
    # (n_cells, samples): attractor of each sample, n_attractors for the sink (pursuit)
    fates: np.ndarray | None = None

    @property
    def n_attractors(self) -> int:
        return self.reach.shape[1]

    def metrics(self, box: int = 5, wada_cells: float = 3.0) -> dict[str, Any]:
        """Basin stability, entropy, boundary dimension, Wada test (:mod:`.basin_metrics`)."""
        return metrics_of(self, box, wada_cells)

    def counts(self) -> dict[str, Any]:
        return {
            "basins": [int(np.sum(self.labels == k)) for k in range(self.n_attractors)],
            "boundary": int(np.sum(self.labels == LABEL_BOUNDARY)),
            "escape": int(np.sum(self.labels == LABEL_ESCAPE)),
            "attractor_cells": [
                int(np.sum(self.attractor_of == k)) for k in range(self.n_attractors)
            ],
        }


def transition_graph(image: np.ndarray, sink: int) -> csr_matrix:
    """Cell-to-cell transition probabilities (the sink maps to itself)."""
    # scipy.sparse here, not at the top: the pursuit and slice methods do not use it,
    # and importing it costs a tenth of a second of every analysis' start
    from scipy.sparse import coo_matrix

    n_cells, samples = image.shape
    src = np.repeat(np.arange(n_cells), samples)
    rows = np.append(src, sink)
    cols = np.append(image.ravel(), sink)
    data = np.append(np.full(src.size, 1.0 / samples), 1.0)
    graph = coo_matrix((data, (rows, cols)), shape=(sink + 1, sink + 1)).tocsr()
    graph.sum_duplicates()
    return graph


def _chain_period(graph: csr_matrix, members: np.ndarray) -> int:
    """gcd of the cycle lengths inside a communicating class (BFS levels)."""
    inside = np.zeros(graph.shape[0], dtype=bool)
    inside[members] = True
    level = np.full(graph.shape[0], -1)
    level[members[0]] = 0
    order = [members[0]]
    period = 0
    k = 0
    while k < len(order):
        u = order[k]
        k += 1
        for v in graph.indices[graph.indptr[u] : graph.indptr[u + 1]]:
            if not inside[v]:
                continue
            if level[v] < 0:
                level[v] = level[u] + 1
                order.append(v)
            else:
                period = math.gcd(period, int(level[u] + 1 - level[v]))
    return max(period, 1)


def persistent_groups(grid: Grid, image: np.ndarray) -> tuple[Any, ...]:
    """The transition graph, its strongly connected components (``comp`` per node,
    ``leaves`` per component), and the persistent groups (closed components other
    than the sink's), largest first."""
    from scipy.sparse.csgraph import connected_components

    graph = transition_graph(image, grid.sink)
    n_comp, comp = connected_components(graph, directed=True, connection="strong")
    coo = graph.tocoo()
    leaves = np.zeros(n_comp, dtype=bool)
    cross = comp[coo.row] != comp[coo.col]
    leaves[comp[coo.row[cross]]] = True
    closed = [c for c in range(n_comp) if not leaves[c] and c != comp[grid.sink]]
    groups = [np.flatnonzero(comp[: grid.n_cells] == c) for c in closed]
    groups.sort(key=lambda m: (-m.size, m[0]))  # a stable numbering for reports
    return graph, comp, leaves, groups


def classify_cells(
    grid: Grid, graph: csr_matrix, comp: np.ndarray, leaves: np.ndarray, attractors: list
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """Given each attractor's cells: which attractors every cell reaches, the cell
    labels (basin, boundary, escape) and the saddle groups."""
    from scipy.sparse.csgraph import breadth_first_order

    attractor_of = np.full(grid.n_cells, -1)
    reach = np.zeros((grid.n_cells, len(attractors)), dtype=bool)
    reverse = graph.T.tocsr()
    for k, cells in enumerate(attractors):
        attractor_of[cells] = k
        for start in np.unique(comp[cells]):  # one start per communicating class
            node = int(cells[np.argmax(comp[cells] == start)])
            reached = breadth_first_order(reverse, node, directed=True)[0]
            reach[reached[reached < grid.n_cells], k] = True
    n_reach = reach.sum(axis=1)
    labels = np.where(n_reach == 0, LABEL_ESCAPE, LABEL_BOUNDARY)
    single = n_reach == 1
    if attractors:
        labels[single] = np.argmax(reach[single], axis=1)
    saddles = []
    self_loop = graph.diagonal() > 0
    for c in np.flatnonzero(leaves):
        cells = np.flatnonzero(comp[: grid.n_cells] == c)
        cyclic = cells.size > 1 or (cells.size == 1 and self_loop[cells[0]])
        if cyclic and np.all(labels[cells] == LABEL_BOUNDARY):
            saddles.append(cells)
    return labels, attractor_of, reach, saddles


def same_motion(a: dict, b: dict, scale: np.ndarray, tol: float = MERGE_TOL) -> bool:
    """Whether two simulated periodic motions are one: same n-m, same stroboscopic
    points (as sets) within ``tol`` state scales."""
    if not (a.get("period") and a.get("label") == b.get("label")):
        return False
    pa = np.asarray(a["poincare_points"]) / scale
    pb = np.asarray(b["poincare_points"]) / scale
    return all(np.any(np.all(np.abs(pb - p) <= tol, axis=1)) for p in pa)


def _motion(smap: StroboscopicMap, grid: Grid, graph: csr_matrix, cells: np.ndarray) -> dict:
    """The attractor's motion by direct simulation from its most visited cell's centre."""
    inflow = np.asarray(graph[:, cells][cells, :].sum(axis=0)).ravel()
    start = grid.centres(np.array([cells[np.argmax(inflow)]]))[0]
    orbit = smap.orbit(start, skip=300, keep=64)
    if not orbit.ok:
        return {"label": "unknown", "message": orbit.message, "start": start.tolist()}
    motion = classify(orbit.points, orbit.impacts, smap.scale)
    n = motion.period or orbit.points.shape[0]
    return {
        "label": motion.label,
        "period": motion.period,
        "impacts": motion.impacts,
        "poincare_points": orbit.points[-n:].tolist(),
        "start": start.tolist(),
    }


def check_inputs(smap: StroboscopicMap, samples: int, seed: int) -> None:
    """One-line errors naming the flag: a 2-D section, ``--samples`` >= 1, ``--seed`` >= 0."""
    if smap.n_state != 2:
        raise MapError(
            f"cell mapping works on a 2-D section (x, x'); this system's state has "
            f"{smap.n_state} components ({', '.join(smap.system.state_names)}); "
            "--slice NAME1,NAME2 follows samples in the full state space"
        )
    check_sampling(samples, seed)


def check_sampling(samples: int, seed: int) -> None:
    """One-line errors naming the flag: ``--samples`` >= 1, ``--seed`` >= 0."""
    if not (isinstance(samples, int) and samples >= 1):
        raise AnalysisError(f"--samples = {samples!r} must be an integer >= 1")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise AnalysisError(f"--seed = {seed!r} must be an integer >= 0")


def cell_mapping(
    smap: StroboscopicMap,
    grid: Grid,
    samples: int,
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: Any = None,
    chunk: int = DEFAULT_CHUNK,
    progress: bool = False,
) -> Basins:
    """Map every cell's samples (in parallel tasks, checkpointed) and analyse the graph."""
    check_inputs(smap, samples, seed)
    images = map_in_chunks(
        smap, grid, samples, seed, map_cells, "cells", "cell_mapping",
        workers, scheduler, checkpoint_dir, chunk, progress,
    )  # fmt: skip
    image = np.concatenate([r["image"] for r in images])
    image = image.reshape(grid.n_cells, samples).astype(np.int64)
    graph, comp, leaves, groups = persistent_groups(grid, image)
    # Coarse cells can split one attractor into several persistent groups (a cell whose
    # few samples all stay in it); groups whose simulated motions coincide are merged.
    motions: list[dict[str, Any]] = []
    attractors: list[list[np.ndarray]] = []
    for cells in groups:
        motion = _motion(smap, grid, graph, cells)
        for k, known in enumerate(motions):
            if same_motion(known, motion, smap.scale):
                attractors[k].append(cells)
                break
        else:
            motions.append(motion)
            attractors.append([cells])
    merged = [np.sort(np.concatenate(a)) for a in attractors]
    labels, attractor_of, reach, saddles = classify_cells(grid, graph, comp, leaves, merged)
    periods = [_chain_period(graph, a[0]) for a in attractors]
    for motion, parts in zip(motions, attractors, strict=True):
        motion["persistent_groups"] = len(parts)
        motion["points_in_group"] = float(
            np.mean(
                np.isin(
                    grid.cell_of(np.asarray(motion.get("poincare_points", [[np.nan] * 2]))),
                    np.concatenate(parts),
                )
            )
        )
    return Basins(
        grid, samples, seed, image, labels, attractor_of, reach, saddles, periods, motions
    )
