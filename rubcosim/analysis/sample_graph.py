"""The sample-to-sample graph of a stroboscopic map: every sample point of a cell grid
is mapped one forcing period, and its image is tied to the nearest sample point.

Generalized cell mapping ties an image to its *cell*; when the map is close
to the identity (multipliers near 1 in modulus, as near a weakly damped focus
or a weak saddle) one-period images stay in or next to their cell and the
cell graph grows spurious closed classes.  Tying each image to the nearest of
the ``nx * nv * samples`` sample points instead gives a functional graph (one
successor per sample) whose resolution is the sample spacing, several times
finer than a cell: following it is following each sample's own trajectory,
with an error of at most about half a sample spacing per period.  Its terminal
cycles are where the chains end; which attractor each cycle belongs to is
decided by direct simulation (:mod:`.attractors`).
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from .cellmap import Grid, sample_cells
from .maps import StroboscopicMap, admissible
from .sample_index import SampleIndex

SINK = -1  # successor of a sample whose image leaves the region or whose run failed


def map_samples(
    smap: StroboscopicMap, grid: Grid, first: int, last: int, samples: int, seed: int
) -> dict[str, np.ndarray]:
    """One task: the one-period image (state units; NaN when the run failed or the sample
    is inside an obstacle) of every sample of cells ``first .. last - 1``, rows in cell
    order, and its impacts.  The samples are :func:`.cellmap.sample_cells`'s, so the same
    seed gives the same points as the cell mapping."""
    states = sample_cells(grid, first, last, samples, seed)
    ok = admissible(smap, states)
    images, _, impacts, status = smap.map(states)
    images[(status != 0) | ~ok] = np.nan
    return {"image": images, "impacts": impacts.astype(np.int16)}


def successors(
    grid: Grid, points: np.ndarray, images: np.ndarray, k: int = 1
) -> tuple[np.ndarray, np.ndarray, SampleIndex]:
    """Index of the sample point nearest to each image (distances in cell widths, so
    both axes weigh alike), :data:`SINK` for images outside the region or not finite;
    the ``k`` nearest (rows of indices, nearest first; 0 for images outside); the
    sample points' index (``points``: every cell's samples, in cell order)."""
    index = SampleIndex(grid, points, points.shape[0] // grid.n_cells)
    inside = grid.cell_of(images) != grid.sink
    nxt = np.full(points.shape[0], SINK, dtype=np.int64)
    near = np.zeros((points.shape[0], k), dtype=np.int64)
    near[inside] = index.query(images[inside], k)
    nxt[inside] = near[inside, 0]
    return nxt, near, index


@nb.njit(cache=True)
def terminal_cycles(nxt: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """For each node of the functional graph ``nxt`` (successor index, or < 0: the
    sink), the node at which its chain closes a cycle (one node per cycle, the same
    for every chain into it), or -1 when the chain ends in the sink.  O(N)."""
    n = nxt.shape[0]
    state = np.zeros(n, dtype=np.int8)  # 0 new, 1 on the current walk, 2 settled
    term = np.full(n, -1, dtype=np.int64)
    walk = np.empty(n, dtype=np.int64)
    for s in range(n):
        if state[s] != 0:
            continue
        top = 0
        u = s
        while u >= 0 and state[u] == 0:
            state[u] = 1
            walk[top] = u
            top += 1
            u = nxt[u]
        if u < 0:
            t = -1
        elif state[u] == 1:  # the walk closed a new cycle at u
            t = u
        else:
            t = term[u]
        for k in range(top):
            term[walk[k]] = t
            state[walk[k]] = 2
    return term


def cycle_members(nxt: np.ndarray, start: int) -> np.ndarray:
    """The nodes of the cycle through ``start``, in order."""
    out = [start]
    u = int(nxt[start])
    while u != start:
        out.append(u)
        u = int(nxt[u])
    return np.array(out, dtype=np.int64)


def sample_graph(grid: Grid, points: np.ndarray, images: np.ndarray, k: int = 1) -> dict[str, Any]:
    """Successors, the ``k`` samples nearest to each image (``near``), the points'
    ``index`` (:class:`.sample_index.SampleIndex`), each sample's terminal cycle node
    (-1: the sink) and the cycles (their nodes, largest drainage first)."""
    nxt, near, index = successors(grid, points, images, k)
    term = terminal_cycles(nxt)
    heads, drained = np.unique(term[term >= 0], return_counts=True)
    order = np.argsort(-drained, kind="stable")
    return {
        "next": nxt,
        "near": near,
        "index": index,
        "terminal": term,
        "cycles": heads[order],
        "drained": drained[order],
    }
