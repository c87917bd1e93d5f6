"""Which ties of the sample graph can be trusted, and the exact tracking of the others.

The sample graph (:mod:`.sample_graph`) replaces each sample's one-period
image ``P(s)`` by the nearest sample ``s'``, an error of up to about half a
sample spacing per period.  Far from a basin boundary that error is harmless
(``P(s)`` and ``s'`` go to the same attractor); within a sample spacing of a
boundary it decides the fate, and where the basins are thin interleaved bands
(Feng & Yang's case) a chain of ties can cross a band and carry a sample to
the wrong attractor.  So a tie is used only where the samples show that it
cannot change the fate:

1. *anchors* are the samples whose fate is known without ties: those inside a
   verified attractor neighbourhood (direct simulation from the cells), and
   the graph's cycle heads (each pursued by direct simulation, :func:`.attractors.settle`);
   a sample whose image leaves the region goes to the sink (its image is exact);
2. every other sample takes, provisionally, the fate of the first anchor down
   its chain of ties;
3. a tie ``s -> s'`` is *safe* when the ``K_NEAR`` samples nearest to the image
   ``P(s)`` (a ball several times the tie's own error) all have one fate: the
   image then lies inside one basin at the sample resolution;
4. a sample is *trusted* when it is an anchor, or its tie is safe and its
   successor is trusted (every tie down its chain is safe);
5. every sample that is not trusted is *tracked*: its exact image is mapped one
   period at a time (the compiled map, all of them per call) until it leaves the
   region (the sink), enters a verified neighbourhood, or lands where its
   ``K_NEAR`` nearest samples are all trusted and share one fate; those still
   undecided after ``TRACK_MAX`` periods are pursued to a verified neighbourhood
   (:func:`.attractors.pursue`).

What remains is the sampling's own resolution: a band thinner than the sample
spacing that no sample falls in is invisible to this test (and to any method
with these samples).
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from .attractors import Attractor, pursue
from .cellmap import Grid
from .maps import StroboscopicMap
from .sample_index import SampleIndex
from .tie_passes import (
    dependency_order,
    fates_in_order,
    safe_ties,
    shared_fate,
    successor_positions,
    trust_in_order,
)

K_NEAR = 8  # samples nearest to an image that must share one fate (16 per cell: ~0.4 cell)
TRACK_MAX = 150  # periods a sample that is not trusted is followed exactly
SINK = 1 << 30  # the sink's fate while attractors may still be added (len(known) at the end)
# Tracked samples fewer than 1/FEW_TRACKED of all: the trust passes (three compiled
# sweeps over every sample, ~20 ms for 640,000) cost more than mapping them (~8 us
# each on 2 workers), so they run every PASS_EVERY rounds.
FEW_TRACKED = 256
PASS_EVERY = 8


@nb.njit(cache=True)
def agreed_fate(near, fate, ok):  # pragma: no cover - compiled
    """Per row of neighbour indices ``near``: the fate all of them share, all ``ok``,
    else -1."""
    out = np.empty(near.shape[0], dtype=np.int64)
    for r in range(near.shape[0]):
        out[r] = shared_fate(near, r, fate, ok)
    return out


def _decide(space: Any, grid: Grid, index: SampleIndex, y: np.ndarray, fate, ok, known) -> Any:
    """Per exact state ``y``: :data:`SINK` outside the region, the attractor whose
    verified neighbourhood holds it, or the fate its ``K_NEAR`` nearest samples (their
    ``fate``, all trusted: ``ok``) share; else -1."""
    decided = np.full(y.shape[0], -1, dtype=np.int64)
    outside = grid.cell_of(y) == grid.sink
    decided[outside] = SINK
    inside = np.flatnonzero(~outside)
    hood = space.locate(y[inside], known)
    decided[inside] = hood
    free = inside[hood < 0]
    if free.size:
        decided[free] = agreed_fate(index.query(y[free], K_NEAR), fate, ok)
    return decided


def _trust_pass(order, reached, succ, anchor, nxt, near, fate, safe, ok) -> None:
    """Every sample's provisional ``fate``, whether its tie is ``safe`` and whether it
    is trusted (``ok``), from the ``anchor``s: one compiled pass each, in place."""
    # a cycle without an anchor cannot occur (SINK for it: never a label)
    fates_in_order(order, reached, succ, anchor, SINK, SINK, fate)
    safe_ties(nxt, near, fate, safe)
    trust_in_order(order, reached, succ, anchor, safe, ok)


def settle_samples(
    smap: StroboscopicMap,
    space: Any,
    grid: Grid,
    points: np.ndarray,
    images: np.ndarray,
    graph: dict[str, Any],
    heads_fate: np.ndarray,
    known: list[Attractor],
    mapper: Any = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Every sample's fate (attractor index, ``len(known)`` for the sink) from the
    sample graph ``graph`` (:func:`.sample_graph.sample_graph`, with its ``near``
    neighbours and ``index``) and its cycle heads' fates ``heads_fate`` (-1: failed),
    using only trusted ties and tracking the other samples (see the module doc);
    ``space`` holds the verified neighbourhoods (:class:`.state_space.StateSpace`).
    ``mapper(states)``: the one-period images of many states (default ``smap.map``'s).

    Tracking goes by rounds: each round, trust is worked out again with the samples
    decided so far as anchors, and only the samples whose own tie is unsafe are
    mapped one more period; a sample that only inherits distrust from one of them
    becomes trusted as soon as that one is decided, without a map of its own."""
    mapper = mapper or (lambda y: smap.map(y)[0])
    nxt, near, index = graph["next"], np.ascontiguousarray(graph["near"]), graph["index"]
    n = points.shape[0]
    anchor = space.locate(points, known)
    heads = graph["cycles"]
    free_heads = anchor[heads] < 0
    anchor[heads[free_heads]] = np.where(heads_fate >= 0, heads_fate, SINK)[free_heads]
    # every cycle now holds an anchor (its head): fate and trust are one pass each
    order, reached = dependency_order(nxt, anchor >= 0)
    succ = successor_positions(order, nxt)
    fate, safe, ok = np.empty(n, dtype=np.int64), np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    y = images.copy()  # the exact state of every sample tracked so far
    done = np.zeros(n, dtype=np.int64)  # periods each sample was tracked
    stats = {
        "anchors": int(np.sum(anchor >= 0)),
        "tracked_periods": 0,
        "rounds": 0,
        "trust_passes": 0,
    }
    roots, last_pass = np.empty(0, dtype=np.int64), -PASS_EVERY
    for step in range(TRACK_MAX + 1):
        # Few samples left: the passes over every sample cost more than their maps, so
        # they run every PASS_EVERY rounds only; in between the tracked samples go on
        # and the decided ones drop out.  A tie made unsafe by a new anchor waits for
        # the next pass, and tracking ends only on a pass that finds nothing to track.
        lazy = roots.size and roots.size * FEW_TRACKED < n and step - last_pass < PASS_EVERY
        roots = roots[anchor[roots] < 0] if lazy else roots
        if not lazy or roots.size == 0:
            _trust_pass(order, reached, succ, anchor, nxt, near, fate, safe, ok)
            roots, last_pass = np.flatnonzero(~ok & ~safe & (anchor < 0)), step
            stats["trust_passes"] += 1
        if step == 0:
            stats |= {"unsafe_ties": int(np.sum(~safe)), "untrusted": int(np.sum(~ok))}
        if roots.size == 0:
            break
        if step:
            y[roots] = mapper(y[roots])
            done[roots] += 1
            stats["tracked_periods"] += int(roots.size)
            stats["rounds"] += 1
        decided = _decide(space, grid, index, y[roots], fate, ok, known)
        new = roots[decided >= 0]
        anchor[new] = decided[decided >= 0]
        if not np.all(reached[new]):  # an anchor on a cycle that had none: order again
            order, reached = dependency_order(nxt, anchor >= 0)
            succ = successor_positions(order, nxt)
    else:  # TRACK_MAX periods tracked: what is still undecided, by a last pass
        _trust_pass(order, reached, succ, anchor, nxt, near, fate, safe, ok)
    left = np.flatnonzero(~ok & ~safe & (anchor < 0))
    if left.size:  # still undecided after TRACK_MAX periods: pursued, then classified
        pursued, more = pursue(smap, space, y[left], known)
        anchor[left] = np.where(pursued >= 0, pursued, SINK)
        stats["tracked_periods"] += int(more)
        order, reached = dependency_order(nxt, anchor >= 0)
        succ = successor_positions(order, nxt)
        fates_in_order(order, reached, succ, anchor, SINK, SINK, fate)
    stats |= {"tracked": int(np.sum(done > 0)), "tracked_then_pursued": int(left.size)}
    fate[fate == SINK] = len(known)  # pursuit may have found new attractors
    return fate, stats
