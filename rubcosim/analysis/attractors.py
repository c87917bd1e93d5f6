"""Attractors found and verified by direct simulation, and the samples' pursuit to them.

An attractor is found by iterating the stroboscopic map from a point for
``SETTLE`` periods and classifying the next ``KEEP`` points with
:func:`.motion.classify` (n-m, or not periodic).  Its *verified
neighbourhood* is a set from which direct simulation goes to it (a ball
around each of its points, :mod:`.state_space`; a motion that is not periodic
is followed ``CHAOS_KEEP`` periods for its points, and its largest Lyapunov
exponent over them, ``motion["lyapunov"]`` in 1/s, tells chaos from
quasi-periodicity).

A point is *pursued* by mapping it ``PURSUE_STEP`` periods at a time (the
compiled multi-period map, many points per call) until it enters a verified
neighbourhood; one that has not after ``PURSUE_MAX`` periods is simulated and
classified, which finds a new attractor or a known one.

Where a neighbourhood lives is the *space*'s business
(:class:`.state_space.StateSpace`, for ``--method pursuit`` and ``--method slice``):
:func:`identify`, :func:`pursue` and :func:`settle` take it as an argument.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import AnalysisError
from .lyapunov import lyapunov_spectrum
from .maps import StroboscopicMap
from .motion import classify

SETTLE = 600  # periods before classifying: multipliers of modulus 0.91 shrink by 1e-25
KEEP = 64  # periods classified
CLASSIFY_TOL = 1e-5  # state scales: a settled periodic orbit repeats far closer
MATCH_TOL = 1e-3  # state scales: the same periodic attractor
CHAOS_KEEP = 2000  # periods of a non-periodic attractor whose cells are its neighbourhood
PURSUE_STEP = 20  # periods per pursuit call
PURSUE_MAX = 600  # periods pursued before simulating and classifying
IDENTIFY_FIRST = 8  # starts simulated one by one (in order) before batch pursuit


@dataclass
class Attractor:
    """A verified attractor: its motion (``label`` n-m or not periodic, ``period``,
    ``impacts``, ``poincare_points``), the cells it occupies and its neighbourhood."""

    motion: dict[str, Any]
    points: np.ndarray  # points on the attractor (the n points, or CHAOS_KEEP of them)
    cells: np.ndarray  # cell numbers of those points (the sink dropped)
    near: np.ndarray  # bool per cell (unused by the state-space neighbourhoods: all False)
    radius: float = 0.0  # state scales: its verified ball around each point (StateSpace)

    @property
    def periodic(self) -> bool:
        return bool(self.motion.get("period"))


def _motion(smap: StroboscopicMap, start: np.ndarray) -> tuple[dict[str, Any], Any]:
    orbit = smap.orbit(start, skip=SETTLE, keep=KEEP)
    if not orbit.ok:
        return {"label": "unknown", "message": orbit.message, "start": start.tolist()}, orbit
    m = classify(orbit.points, orbit.impacts, smap.scale, tol=CLASSIFY_TOL)
    n = m.period or orbit.points.shape[0]
    motion = {
        "label": m.label,
        "period": m.period,
        "impacts": m.impacts,
        "poincare_points": orbit.points[-n:].tolist(),
        "start": start.tolist(),
        "periodic": m.periodic,
        "settle_periods": SETTLE,
    }
    return motion, orbit


def converges_to(
    smap: StroboscopicMap, starts: np.ndarray, points: np.ndarray, n: int
) -> np.ndarray:
    """Whether the orbit from each start is on the n-periodic ``points`` after
    ``SETTLE`` periods (one compiled call for all starts)."""
    ends, _, _, status = smap.map(starts, periods=SETTLE)
    ok = np.zeros(starts.shape[0], dtype=bool)
    if status.size == 0:
        return ok
    d = np.abs(ends[:, None, :] - points[None, :, :]) / smap.scale
    with np.errstate(invalid="ignore"):
        ok = (status == 0) & np.any(np.all(d <= MATCH_TOL, axis=2), axis=1)
    return ok


def identify(smap: StroboscopicMap, space: Any, start: np.ndarray, known: list[Attractor]) -> int:
    """Simulate from ``start``: the index of the attractor it settles on, appending a
    new verified one (in ``space``, a :class:`.state_space.StateSpace`) to ``known``
    when needed; -1 when the run fails."""
    motion, orbit = _motion(smap, start)
    if motion["label"] == "unknown":
        return -1
    k = space.match(smap, motion, known)
    if k >= 0:
        return k
    known.append(space.build(smap, motion, orbit))
    return len(known) - 1


def pursue(
    smap: StroboscopicMap, space: Any, starts: np.ndarray, known: list[Attractor]
) -> tuple[np.ndarray, int]:
    """Where each start goes: its attractor index (-1: the run failed), found by
    mapping all of them ``PURSUE_STEP`` periods at a time until each is in a verified
    neighbourhood of ``space``, simulating and classifying those that are not after
    ``PURSUE_MAX`` (which may add attractors to ``known``).  Also returns the periods
    mapped."""
    fate = space.locate(starts, known)
    todo = np.flatnonzero(fate < 0)
    y = starts[todo].copy()
    mapped = 0
    for _ in range(PURSUE_MAX // PURSUE_STEP):
        if todo.size == 0:
            break
        y, _, _, status = smap.map(y, periods=PURSUE_STEP)
        mapped += PURSUE_STEP * todo.size
        k = space.locate(y, known)
        failed = status != 0
        fate[todo[failed]] = -1
        fate[todo[k >= 0]] = k[k >= 0]
        left = (k < 0) & ~failed
        todo, y = todo[left], y[left]
    for t, yt in zip(todo, y, strict=True):
        fate[t] = identify(smap, space, yt, known)
    return fate, mapped


def settle(
    smap: StroboscopicMap, space: Any, starts: np.ndarray
) -> tuple[np.ndarray, list[Attractor], dict[str, int]]:
    """The attractor index of every start (-1: its run failed) and the attractors found:
    in order, the first start outside every verified neighbourhood is simulated and
    classified (``IDENTIFY_FIRST`` of them at most), the rest pursued in one batch."""
    known: list[Attractor] = []
    fate = np.full(starts.shape[0], -2, dtype=np.int64)  # -2: not decided yet
    simulated = 0
    while simulated < IDENTIFY_FIRST:
        left = np.flatnonzero(fate == -2)
        k = space.locate(starts[left], known)
        fate[left[k >= 0]] = k[k >= 0]
        out = left[k < 0]
        if out.size == 0:
            break
        fate[out[0]] = identify(smap, space, starts[out[0]], known)
        simulated += 1
    rest = np.flatnonzero(fate == -2)
    outside = int(np.sum(space.locate(starts[rest], known) < 0))
    pursued, mapped = pursue(smap, space, starts[rest], known)
    fate[rest] = pursued
    stats = {
        "starts": int(starts.shape[0]),
        "simulated": simulated,
        "pursued": outside,
        "pursuit_periods": int(mapped),
    }
    return fate, known, stats


def largest_exponent(smap: StroboscopicMap, orbit: Any) -> float | str:
    """The largest Lyapunov exponent (1/s) over ``CHAOS_KEEP`` periods from the end of
    ``orbit`` (an :class:`~.maps.Orbit`), or why it could not be measured."""
    try:
        lyap = lyapunov_spectrum(
            smap.system, CHAOS_KEEP, 0, rtol=smap.rtol, y0=orbit.final_state,
            mode=orbit.mode, count=1,
        )  # fmt: skip
    except AnalysisError as exc:
        return f"not measured: {exc}"
    return lyap.largest
