"""Fates and trust over the sample graph in one linear pass each (:mod:`.trusted_ties`).

The sample graph is functional (one successor per sample, ``nxt[u] < 0``: the
sink).  A sample's fate is that of the first anchor down its chain, and it is
trusted when every tie down to that anchor is safe: both are fixed by the
successor's.  Once every cycle holds an anchor (the cycle heads are anchored
before tracking starts), the samples can be put in an order where each comes
after its successor (:func:`dependency_order`: a breadth-first walk up the
ties from the anchors and the samples that leave the region), and then fate
and trust are one pass down that order each instead of a walk per chain.
New anchors only cut chains, so the order stays valid while tracking adds
them; a sample the walk cannot reach (a cycle without an anchor) keeps fate -1
and is never trusted, and the order is rebuilt if such a sample gets anchored.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def dependency_order(nxt: np.ndarray, anchored: np.ndarray):  # pragma: no cover - compiled
    """``(order, reached)``: the samples each after its successor (anchors and samples
    whose successor is the sink first), and whether each was reached; the samples not
    reached (on or upstream of a cycle without an anchor) are at the end of ``order``."""
    n = nxt.shape[0]
    count = np.zeros(n + 1, dtype=np.int64)
    for u in range(n):
        if not anchored[u] and nxt[u] >= 0:
            count[nxt[u] + 1] += 1
    for u in range(n):
        count[u + 1] += count[u]
    start = count[:n].copy()
    pred = np.empty(count[n], dtype=np.int64)
    fill = start.copy()
    for u in range(n):
        if not anchored[u] and nxt[u] >= 0:
            pred[fill[nxt[u]]] = u
            fill[nxt[u]] += 1
    order = np.empty(n, dtype=np.int64)
    reached = np.zeros(n, dtype=np.bool_)
    top = 0
    for u in range(n):
        if anchored[u] or nxt[u] < 0:
            order[top] = u
            reached[u] = True
            top += 1
    head = 0
    while head < top:
        v = order[head]
        head += 1
        for e in range(start[v], count[v + 1]):
            order[top] = pred[e]
            reached[pred[e]] = True
            top += 1
    for u in range(n):
        if not reached[u]:
            order[top] = u
            top += 1
    return order, reached


@nb.njit(cache=True)
def successor_positions(order: np.ndarray, nxt: np.ndarray) -> np.ndarray:  # pragma: no cover
    """Position in ``order`` of each ordered sample's successor (-1: the sink), so the
    passes below read the successor's value from a vector they fill in order."""
    pos = np.empty(order.shape[0], dtype=np.int64)
    for i in range(order.shape[0]):
        pos[order[i]] = i
    out = np.empty(order.shape[0], dtype=np.int64)
    for i in range(order.shape[0]):
        v = nxt[order[i]]
        out[i] = pos[v] if v >= 0 else -1
    return out


@nb.njit(cache=True)
def fates_in_order(order, reached, succ, anchor, sink, lost, fate):  # pragma: no cover
    """``fate[u]``: ``anchor`` of the first anchor down u's chain, ``sink`` when the
    chain leaves the region first, ``lost`` when it was not reached (no anchor on its
    cycle); ``succ``: :func:`successor_positions`."""
    along = np.empty(order.shape[0], dtype=np.int64)  # fate by position in the order
    for i in range(order.shape[0]):
        u = order[i]
        if anchor[u] >= 0:
            f = anchor[u]
        elif not reached[u]:
            f = lost
        elif succ[i] < 0:
            f = sink
        else:
            f = along[succ[i]]
        along[i] = f
        fate[u] = f


@nb.njit(cache=True)
def trust_in_order(order, reached, succ, anchor, safe, ok):  # pragma: no cover - compiled
    """``ok[u]``: u is an anchor, or its tie is ``safe`` and leads to the sink (exact)
    or to a trusted sample; never for a sample not reached."""
    along = np.empty(order.shape[0], dtype=np.bool_)
    for i in range(order.shape[0]):
        u = order[i]
        if anchor[u] >= 0:
            t = True
        elif not reached[u]:
            t = False
        else:
            t = safe[u] and (succ[i] < 0 or along[succ[i]])
        along[i] = t
        ok[u] = t


@nb.njit(cache=True, inline="always")
def shared_fate(near, r, fate, ok):  # pragma: no cover - compiled
    """The fate every sample of row ``r`` of ``near`` has (and every one of them ``ok``,
    unless ``ok`` is None), else -1."""
    f = fate[near[r, 0]]
    for c in range(near.shape[1]):
        u = near[r, c]
        if fate[u] != f:
            return -1
        if ok is not None and not ok[u]:
            return -1
    return f


# parallel: each sample on its own (the other passes follow the ties, in order); it runs
# between the tracking's rounds, while the workers wait
@nb.njit(cache=True, parallel=True)
def safe_ties(nxt, near, fate, safe):  # pragma: no cover - compiled
    """``safe[u]``: the samples nearest to u's image (row ``near[u]``) all have one fate
    (>= 0); an image outside the region (``nxt[u] < 0``) is exact, so its tie is safe."""
    for u in nb.prange(nxt.shape[0]):
        safe[u] = nxt[u] < 0 or shared_fate(near, u, fate, None) >= 0
