"""The delayed-feedback controller's history: interpolation of its samples at a past time.

The controller's kernels (:mod:`.flat_controller`) keep the fed-back signal as rows
``(t, zx, zy, Sx, Sy, kind)`` taken at the communication points.  :func:`_lookup`
evaluates the signal and the ETDAS filter at a time ``tq`` by cubic Lagrange
interpolation through the four samples around it, each within its own continuous pieces
(two samples at one time mark a jump, or a kink when they are equal: an event that left
a fed-back position continuous and reset its slope; at that time ``left`` takes the left
limit; a jump or kink of the filter alone, a pair of kind ``FILTER_PAIR``, leaves z
continuous and splits no z stencil); the first sample before the first time.
"""

from __future__ import annotations

import numpy as np

from .jit import njit

# a history row: (t, zx, zy, Sx, Sy, kind); kind: a sample of the signal (a step's, or
# its left limit at an event), or one of the pair that marks a jump or kink of S alone
ROW = 6
SAMPLE, FILTER_PAIR = 0.0, 1.0


@njit
def _search(samples, rows, lo, hi, tq, left):  # pragma: no cover - compiled
    """numpy's ``searchsorted`` of ``tq`` among the times of ``rows[lo:hi]`` (an index
    into ``rows``): the first position whose time is >= ``tq`` (``left``) or > ``tq``."""
    while lo < hi:
        mid = (lo + hi) // 2
        t = samples[rows[mid], 0]
        if t < tq or (not left and t == tq):
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit
def _interpolate_rows(samples, rows, m, tq, left, c0, out, o):  # pragma: no cover - compiled
    """Columns ``c0``, ``c0 + 1`` of the sequence ``samples[rows[:m]]`` at ``tq``, into
    ``out[o]``, ``out[o + 1]``: cubic Lagrange through the four rows around it, within the
    continuous piece holding ``tq`` (two rows at one time mark a jump: at that time
    ``left`` takes the piece ending there, the left limit); the first row before the
    first time."""
    t0 = samples[rows[0], 0]
    if tq < t0 or (tq == t0 and (left or m == 1 or samples[rows[1], 0] != t0)):
        out[o] = samples[rows[0], c0]
        out[o + 1] = samples[rows[0], c0 + 1]
        return
    pos = _search(samples, rows, 0, m, tq, left)
    start, stop = 0, m  # the piece: from the last jump at or before pos to the next one
    for k in range(min(pos, m - 1), 0, -1):
        if samples[rows[k], 0] == samples[rows[k - 1], 0]:
            start = k
            break
    for k in range(pos + 1, m):
        if samples[rows[k], 0] == samples[rows[k - 1], 0]:
            stop = k
            break
    i = _search(samples, rows, start, stop, tq, True) - start
    first = start + max(min(i - 2, stop - start - 4), 0)
    last = min(first + 4, stop)
    a0, a1 = 0.0, 0.0
    for p in range(first, last):
        w = 1.0
        tp = samples[rows[p], 0]
        for q in range(first, last):
            if q != p:
                tq_ = samples[rows[q], 0]
                w *= (tq - tq_) / (tp - tq_)
        a0 += w * samples[rows[p], c0]
        a1 += w * samples[rows[p], c0 + 1]
    out[o] = a0
    out[o + 1] = a1


@njit
def _filter_only(samples, r):  # pragma: no cover - compiled
    """Whether row ``r`` is the second row of a jump or kink of the filter alone (no
    sample of the signal: the signal's interpolation skips it)."""
    if r == 0 or samples[r, 0] != samples[r - 1, 0]:
        return False
    same_z = samples[r, 1] == samples[r - 1, 1] and samples[r, 2] == samples[r - 1, 2]
    return same_z and (samples.shape[1] <= 5 or samples[r, 5] == FILTER_PAIR)


@njit
def first_kept(samples, keep):  # pragma: no cover - compiled
    """The first row of ``samples`` a history must keep to look up every time from
    ``keep`` on as before: three samples of the signal before ``keep`` (a stencil
    clamped by the end of its piece reaches three samples back; the second row of a
    jump of the filter alone is no sample of the signal), and never one row of a
    jump without the other."""
    first, count = int(np.searchsorted(samples[:, 0], keep)), 0
    while first > 0 and count < 3:
        first -= 1
        if not _filter_only(samples, first):
            count += 1
    while first > 0 and samples[first, 0] == samples[first - 1, 0]:
        first -= 1
    return first


@njit
def _lookup(samples, tq, left, out):  # pragma: no cover - compiled
    n = samples.shape[0]
    rows = np.empty(n, dtype=np.int64)
    m = 0
    for r in range(n):  # the signal: without the second row of a jump of the filter alone
        if _filter_only(samples, r):
            continue
        rows[m] = r
        m += 1
    _interpolate_rows(samples, rows, m, tq, left, 1, out, 0)
    for r in range(n):
        rows[r] = r
    _interpolate_rows(samples, rows, n, tq, left, 3, out, 2)
