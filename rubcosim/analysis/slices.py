"""Basins over a 2-D slice of initial conditions of any delay-free system (``--method slice``).

Two state components (``--slice NAME1,NAME2``, names as in ``system.state_names``;
default the first two) vary over the grid's region; the others keep the
scenario's initial values (a rotor's x, y at rest; the two-DOF oscillator's
x2, v2 with x1, v1 at rest).  A cell-to-cell map is not closed on such a slice
(images leave it), so every sample is followed in the FULL state space:

1. every sample's full initial state is mapped ``FOLLOW`` forcing periods by the
   compiled multi-period map, in parallel checkpointed chunks
   (:func:`.parallel.map_in_chunks`): the bulk of the cost;
2. the end states are settled on verified attractors (:func:`.attractors.settle`,
   as the pursuit method settles its cycles): in order, the first end state
   outside every verified neighbourhood is simulated and classified n-m (or not
   periodic), the rest are pursued ``PURSUE_STEP`` periods at a time until they
   enter one.  Neighbourhoods live in the full state space (:class:`.state_space.StateSpace`):
   a ball of verified radius (state scales, max norm) around each point of a
   periodic attractor, or around the points of a non-periodic one's orbit;
3. a sample whose end state is beyond ``ESCAPE_SCALES`` state scales, whose run
   fails, or which starts inside a rigid obstacle goes to the sink (escape);
4. per cell, the share of its samples per attractor; basin, boundary (mixed) and
   escape cells as for the pursuit method (:func:`.pursuit.tally`).

An attractor's ``cells`` are those holding the projections of its stroboscopic
points onto the slice (on the default slice of a 2-D system, its own cells).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .attractors import settle
from .cellmap import DEFAULT_CHUNK, Basins, Grid, check_sampling, sample_cells
from .errors import AnalysisError
from .maps import StroboscopicMap, admissible
from .parallel import map_in_chunks
from .pursuit import tally
from .state_space import StateSpace

FOLLOW = 100  # periods every sample is mapped before its end state is settled
ESCAPE_SCALES = 1e3  # state scales: a state farther out on any component has escaped


def parse_slice(system: Any, names: str | Sequence[str] | None) -> tuple[int, int]:
    """The state indices of the slice ``"NAME1,NAME2"`` (or a pair of names); the first
    two components when ``None``.  Errors name ``--slice``."""
    state = list(system.state_names)
    if getattr(system, "has_delay", False):
        raise AnalysisError(
            f"--slice {names!r}: this system has a delay (its state is its history); "
            "basins take delay-free systems only"
        )
    if names is None:
        if len(state) < 2:
            raise AnalysisError(f"--slice: the state has {len(state)} component(s), needs 2")
        return 0, 1
    parts = [p.strip() for p in names.split(",")] if isinstance(names, str) else list(names)
    if len(parts) != 2:
        raise AnalysisError(f"--slice {names!r}: expected NAME1,NAME2 (two state names)")
    for p in parts:
        if p not in state:
            raise AnalysisError(f"--slice {names!r}: {p!r} is not one of {', '.join(state)}")
    if parts[0] == parts[1]:
        raise AnalysisError(f"--slice {names!r}: the same state twice; give two different ones")
    return state.index(parts[0]), state.index(parts[1])


def slice_states(smap: StroboscopicMap, points: np.ndarray, axes: tuple[int, int]) -> np.ndarray:
    """Full initial states: the system's initial state with components ``axes`` set to
    each row of ``points`` (slice coordinates, state units)."""
    states = np.tile(np.asarray(smap.system.y0, dtype=float), (points.shape[0], 1))
    states[:, list(axes)] = points
    return states


def follow_samples(
    smap: StroboscopicMap,
    grid: Grid,
    first: int,
    last: int,
    samples: int,
    seed: int,
    axes: tuple[int, int] = (0, 1),
    periods: int = FOLLOW,
) -> dict[str, np.ndarray]:
    """One task: the full state (state units) after ``periods`` periods of every sample of
    cells ``first .. last - 1`` (rows in cell order; NaN when the run failed, the state
    escaped or the sample starts inside an obstacle)."""
    states = slice_states(smap, sample_cells(grid, first, last, samples, seed), axes)
    ok = admissible(smap, states)
    ends, _, _, status = smap.map(states, periods=periods)
    with np.errstate(invalid="ignore"):
        far = np.any(np.abs(ends) > ESCAPE_SCALES * smap.scale, axis=1)
    ends[(status != 0) | ~ok | far] = np.nan
    return {"end": ends}


def slice_basins(
    smap: StroboscopicMap,
    grid: Grid,
    samples: int,
    seed: int = 0,
    axes: tuple[int, int] = (0, 1),
    run: Mapping[str, Any] | None = None,
) -> Basins:
    """Basins over the slice ``axes`` (state indices) by following every sample in the
    full state space (see the module doc).  ``run``: how the samples are mapped, the
    keywords of :func:`.parallel.map_in_chunks` (``workers``, ``scheduler``,
    ``checkpoint_dir``, ``chunk`` in cells, ``progress``)."""
    check_sampling(samples, seed)
    opt = {"workers": None, "scheduler": None, "checkpoint_dir": None, "progress": False}
    opt |= {"chunk": DEFAULT_CHUNK, **(run or {})}
    clock = [time.perf_counter()]
    task = functools.partial(follow_samples, axes=tuple(axes), periods=FOLLOW)
    names = [smap.system.state_names[i] for i in axes]
    chunks = map_in_chunks(
        smap, grid, samples, seed, task, "slice", f"slice {','.join(names)} {FOLLOW}",
        opt["workers"], opt["scheduler"], opt["checkpoint_dir"], opt["chunk"], opt["progress"],
    )  # fmt: skip
    ends = np.concatenate([r["end"] for r in chunks])
    clock.append(time.perf_counter())
    good = np.flatnonzero(np.all(np.isfinite(ends), axis=1))
    fate, known, stats = settle(smap, StateSpace(smap, grid, axes), ends[good])
    clock.append(time.perf_counter())
    label = np.full(ends.shape[0], len(known), dtype=np.int64)  # the sink by default
    label[good] = np.where(fate >= 0, fate, len(known))
    t = tally(grid, samples, label, known)
    end_cells = grid.cell_of(np.nan_to_num(ends[:, list(axes)], nan=np.inf))
    periods = [int(m.get("period") or 0) for m in t["motions"]]
    basins = Basins(
        grid,
        samples,
        seed,
        end_cells.reshape(grid.n_cells, samples),
        t["labels"],
        t["attractor_of"],
        t["reach"],
        [],
        periods,
        t["motions"],
    )
    basins.method = "slice"
    basins.shares = t["shares"]
    basins.fates = t["label"].reshape(grid.n_cells, samples).astype(np.int16)
    sink = int(np.sum(t["label"] == len(known)))
    basins.info = {
        "slice": names,
        "slice_axes": [int(i) for i in axes],
        "fixed_components": {
            n: float(smap.system.y0[i])
            for i, n in enumerate(smap.system.state_names)
            if i not in axes
        },
        "slice_method": {
            **stats,
            "follow_periods": FOLLOW,
            "escape_bound_in_state_scales": ESCAPE_SCALES,
            "sink_samples": sink,
            "sink_sample_fraction": sink / label.size,
            "seconds": {
                "followed": round(clock[1] - clock[0], 3),
                "attractors": round(clock[2] - clock[1], 3),
            },
        },
    }
    return basins
