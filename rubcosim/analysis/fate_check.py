"""A basins result's own check: sampled fates against direct simulation.

Whatever method made it, a basins result says where each sample goes: the pursuit and
slice methods per sample (``Basins.fates``), generalized cell mapping per cell (every
sample of a basin cell goes to its attractor).  :func:`check_fates` draws samples with
a definite fate (not the sink, not a boundary cell), simulates each ``periods`` forcing
periods directly at a tight tolerance, and classifies it by where it ends: within
:data:`AT_ORBIT` state scales (max norm) of a point of a periodic attractor's orbit on
the section, that attractor; else the attractor that is not periodic, if the result has
one.  A result whose fates disagree with direct simulation (an attractor missed, a
basin given to the wrong one) says so: in ``report.json`` and on the terminal.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .cellmap import DEFAULT_CHUNK, Basins, sample_cells
from .maps import StroboscopicMap

DRAW = 100  # samples checked by default
PERIODS = 1000  # forcing periods each is simulated
RTOL = 1e-9  # of the direct simulations
AT_ORBIT = 1e-3  # state scales (max norm): "on the periodic orbit"
LISTED = 10  # disagreeing samples listed in the report


def predicted(b: Basins) -> np.ndarray:
    """The attractor each sample (cell-major, as :func:`.cellmap.all_samples` lays them
    out) goes to by the result, -1 where it says none (sink, boundary cell)."""
    if b.fates is not None:
        fates = b.fates.ravel().astype(np.int64)
        return np.where(fates < b.n_attractors, fates, -1)
    return np.repeat(np.where(b.labels >= 0, b.labels, -1), b.samples)


def sample_points(b: Basins, index: np.ndarray, chunk: int = DEFAULT_CHUNK) -> np.ndarray:
    """The section points of samples ``index`` (cell-major), drawn as the methods draw
    them (one random stream per task of ``chunk`` cells)."""
    out = np.empty((index.size, 2))
    cells = index // b.samples
    for first in np.unique(cells // chunk * chunk):
        last = min(first + chunk, b.grid.n_cells)
        points = sample_cells(b.grid, int(first), int(last), b.samples, b.seed)
        here = (cells >= first) & (cells < last)
        out[here] = points[index[here] - first * b.samples]
    return out


def classify(ends: np.ndarray, motions: list[dict[str, Any]], scale: np.ndarray) -> np.ndarray:
    """The attractor each end state (rows, full state) sits on (see the module's
    docstring); -1 for none."""
    out = np.full(ends.shape[0], -1)
    known = [m.get("label") != "unknown" for m in motions]  # not a failed simulation
    periodic = [m.get("periodic", bool(m.get("period"))) for m in motions]
    for k, m in enumerate(motions):
        if periodic[k] and known[k]:
            orbit = np.asarray(m["poincare_points"], dtype=float)
            d = np.abs(ends[:, None, :] - orbit[None]) / scale
            out[np.min(np.max(d, axis=2), axis=1) < AT_ORBIT] = k
    other = [k for k in range(len(motions)) if not periodic[k] and known[k]]
    if other:
        out[(out < 0) & np.all(np.isfinite(ends), axis=1)] = other[0]
    return out


def check_fates(
    smap: StroboscopicMap,
    b: Basins,
    states_of: Callable[[np.ndarray], np.ndarray] | None,
    draw: int = DRAW,
    periods: int = PERIODS,
    seed: int = 0,
) -> dict[str, Any]:
    """Draw ``draw`` samples with a definite fate (seed ``seed``), simulate each
    ``periods`` periods at :data:`RTOL` from its full state (``states_of`` of its section
    point), and compare; returns what ``report.json`` states as ``fate_check``."""
    start = time.perf_counter()
    fate = predicted(b)
    candidates = np.flatnonzero(fate >= 0)
    n = min(draw, candidates.size)
    out: dict[str, Any] = {"draw": draw, "periods": periods, "rtol": RTOL, "seed": seed}
    if n == 0:
        return {**out, "checked": 0, "agree": 0, "disagree": []}
    pick = np.sort(np.random.default_rng(seed).choice(candidates, n, replace=False))
    points = sample_points(b, pick)
    direct = StroboscopicMap(smap.system, RTOL)
    states = points if states_of is None else states_of(points)
    ends, _, _, _ = direct.map(states, periods=periods)
    scale = np.asarray(smap.scale, dtype=float)
    found = classify(ends, b.motions, scale)
    wrong = np.flatnonzero(found != fate[pick])
    label = [m["label"] for m in b.motions]
    listed = [
        {
            "point": points[i].tolist(),
            "result": f"{fate[pick[i]] + 1}: {label[fate[pick[i]]]}",
            "direct": f"{found[i] + 1}: {label[found[i]]}" if found[i] >= 0 else "none found",
        }
        for i in wrong[:LISTED]
    ]
    out["wall_time_s"] = time.perf_counter() - start
    return {**out, "checked": int(n), "agree": int(n - wrong.size), "disagree": listed}


def verdict(check: dict[str, Any]) -> str:
    """One line for the terminal: how many sampled fates direct simulation confirms."""
    n, agree = check["checked"], check["agree"]
    if n == 0:
        return "no sample has a definite fate to check by direct simulation"
    line = (
        f"{agree} of {n} sampled fates confirmed by direct simulation "
        f"({check['periods']} periods each, rtol {check['rtol']:g})"
    )
    if agree < n:
        line += (
            f"; {n - agree} disagree: this basin structure is not to be trusted "
            "(an attractor missed or a basin misassigned; try --method pursuit, or a "
            "finer grid)"
        )
    return line
