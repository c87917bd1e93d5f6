"""The delayed-feedback controller's history by numpy array operations: a second method
the compiled kernels are held to, bit for bit (``tests/test_flat_controller.py``).

This is how the controller unit kept its history until the unit took the compiled
kernels of :mod:`rubcosim.components.flat_controller` (its step replaced the whole
array with ``np.vstack``; the kernels write into a fixed buffer and move bounds).  The
two agree row for row and output for output, which checks the buffer's bookkeeping
(dropping the future after a step back, the third sample at one time, the filter's
jump rows, the trimmed front, the lookups cut short of the end) against plain array
code that has none of it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rubcosim.components.controller import (
    MODULATION_SHAPES,
    PIECE_TOL,
    base_delay,
    delay_at,
    delayed_arrivals,
    etdas_blend,
    feedback_force,
    piece_index,
    switch_interval,
)
from rubcosim.components.controller_unit import DelayedFeedbackUnit
from rubcosim.components.delay_history import FILTER_PAIR, ROW, SAMPLE, _lookup, first_kept


def lagrange_cubic(ts: np.ndarray, zs: np.ndarray, tq: float) -> np.ndarray:
    """Interpolate rows ``zs`` given at times ``ts`` (up to 4) at ``tq``."""
    out = np.zeros(zs.shape[1])
    for i in range(ts.size):
        w = 1.0
        for j in range(ts.size):
            if j != i:
                w *= (tq - ts[j]) / (ts[i] - ts[j])
        out += w * zs[i]
    return out


def _interpolate_arrays(samples: np.ndarray, tq: float, side: str) -> np.ndarray:
    """:func:`_interpolate_rows` of every row, by array operations."""
    ts = samples[:, 0]
    if tq < ts[0] or (tq == ts[0] and (side == "left" or ts.size == 1 or ts[1] != ts[0])):
        return samples[0, 1:]
    jumps = np.flatnonzero(ts[1:] == ts[:-1]) + 1
    k = int(np.searchsorted(jumps, int(np.searchsorted(ts, tq, side=side)), side="right"))
    start = jumps[k - 1] if k > 0 else 0
    stop = jumps[k] if k < jumps.size else ts.size
    piece = samples[start:stop]
    i = int(np.searchsorted(piece[:, 0], tq))
    lo = max(min(i - 2, piece.shape[0] - 4), 0)
    window = piece[lo : lo + 4]
    return lagrange_cubic(window[:, 0], window[:, 1:], tq)


def lookup_arrays(samples: np.ndarray, tq: float, side: str = "right") -> np.ndarray:
    """:func:`lookup` by array operations (a second method: numpy's searches and slices
    where the kernel loops over rows).  The two agree bit for bit
    (``tests/test_units.py``)."""
    ts = samples[:, 0]
    same_z = np.zeros(ts.size, dtype=bool)
    same_z[1:] = (ts[1:] == ts[:-1]) & np.all(samples[1:, 1:3] == samples[:-1, 1:3], axis=1)
    if samples.shape[1] > 5:  # the second sample of an event's pair splits z (its kink)
        same_z &= samples[:, 5] == FILTER_PAIR
    z = _interpolate_arrays(samples[~same_z][:, :3], tq, side)
    return np.concatenate((z, _interpolate_arrays(samples[:, [0, 3, 4]], tq, side)))


def lookup(samples: np.ndarray, tq: float, side: str = "right") -> np.ndarray:
    """``(zx, zy, Sx, Sy)`` at ``tq`` from rows ``(t, zx, zy, Sx, Sy)``: the signal and
    the filter each interpolated within its own continuous pieces (cubic Lagrange
    through the four samples around ``tq``; two samples at one time mark a jump, or a
    kink when they are equal (an event that left a fed-back position continuous and
    reset its slope), and at that time ``side="left"`` takes the left limit; a jump or
    kink of the filter alone (a pair of kind ``FILTER_PAIR``) leaves z continuous and
    splits no z stencil); the first sample before the first time.  The compiled kernel
    :func:`rubcosim.components.delay_history._lookup`, called as the controller's kernels
    call it."""
    out = np.empty(4)
    _lookup(np.ascontiguousarray(samples, dtype=np.float64), float(tq), side == "left", out)
    return out


class ArrayController(DelayedFeedbackUnit):
    """The controller unit with its history kept by array operations."""

    def _check(self, params: dict[str, Any]) -> None:
        self.tau0 = base_delay(params, params["speed"], self.name, f"{self.name}.speed")

    def _initial_state(self) -> dict[str, Any]:
        # rows (t, zx, zy, Sx, Sy); empty until the first step records a sample, whose
        # time is "start": the constant initial function meets the signal there with a kink
        return {"history": np.zeros((0, ROW)), "start": math.nan}

    def _signal(self) -> tuple[float, float]:
        if self.params["feedback"] == "position":
            return self.u["x"], self.u["y"]
        return self.u["vx"], self.u["vy"]

    def _delay(self, t: float) -> float:
        q = self.params
        shape = MODULATION_SHAPES.index(q["modulation_shape"])
        return delay_at(
            t,
            self.tau0,
            q["modulation_amplitude"],
            q["modulation_frequency"],
            shape,
            q["modulation_seed"],
        )

    def _filter(
        self, samples: np.ndarray, t: float, tq: float | None = None, side: str = "right"
    ) -> tuple[float, float]:
        """The ETDAS filter S(t) from the samples before ``t`` (looked up at ``tq``,
        default ``t - tau(t)``, on ``side`` of a jump there)."""
        memory = self.params["memory"]
        if samples.shape[0] == 0:  # constant initial function: S = z
            return self._signal()
        v = lookup(samples, t - self._delay(t) if tq is None else tq, side)
        return etdas_blend(memory, v[0], v[2]), etdas_blend(memory, v[1], v[3])

    def _filter_jumps(self, hist: np.ndarray, t: float) -> np.ndarray:
        """Rows for the jumps and kinks of the filter between the last sample and
        ``t``: two rows (left and right limit) at each time a recorded jump, or the
        start, arrives (``s - tau(s)`` = its time) and at each jump of a sawtooth or
        telegraph delay, so that no interpolation stencil spans them."""
        if hist.shape[0] == 0:
            return hist
        q = self.params
        shape = MODULATION_SHAPES.index(q["modulation_shape"])
        eps, nu = q["modulation_amplitude"], q["modulation_frequency"]
        t_last = hist[-1, 0]
        ts = hist[:, 0]
        # (arrival time s, delayed time on the left, on the right, lookup side on the left)
        found: list[tuple[float, float, float, str]] = []
        out = np.empty(4)
        for j in np.unique(np.append(ts[1:][ts[1:] == ts[:-1]], self.state["start"])):
            n = delayed_arrivals(j, self.tau0, eps, nu, shape, q["modulation_seed"], out)
            found += [(s, j, j, "left") for s in out[:n] if t_last < s < t]
        width = switch_interval(nu, shape) if eps > 0.0 else math.inf
        m = piece_index(t_last, width) + 1.0 if width < math.inf else math.inf
        while m * width < t:
            s = m * width
            before = (m - 2.0 * PIECE_TOL) * width  # a time in the previous piece
            found.append((s, s - self._delay(before), s - self._delay(s), "right"))
            m += 1.0
        rows: list[list[float]] = []
        zx, zy = self._signal()
        current = [[t, zx, zy, np.nan, np.nan, SAMPLE]]  # z at t: the stencil's right end
        for s, tq_left, tq_right, side in sorted(found):
            known = np.vstack((hist, rows)) if rows else hist
            z = lookup(np.vstack((known, current)), s)
            left = self._filter(known, s, tq_left, side)
            right = self._filter(known, s, tq_right, "right")
            rows += [[s, z[0], z[1], *left, FILTER_PAIR], [s, z[0], z[1], *right, FILTER_PAIR]]
        return np.array(rows).reshape(-1, ROW)

    def _advance(self, t: float, h: float) -> None:
        hist = self.state["history"]
        zx, zy = self._signal()
        if hist.shape[0] and hist[-1, 0] > t:
            hist = hist[hist[:, 0] <= t]  # stepped again from an earlier time: forget the future
        # Two samples at one time mark a jump: a zero-length step recorded the signal just
        # before an impact reset it.  Both stay, and no interpolation stencil spans them;
        # equal ones mark a kink (a position fed back, whose velocity the impact reset).
        # A third sample at that time (events at one time) replaces the second.
        if (
            hist.shape[0] > 1
            and hist[-2, 0] == t
            and hist[-1, 0] == t
            and hist[-1, 1] == zx
            and hist[-1, 2] == zy
        ):
            hist = hist[:-1]
        if math.isnan(self.state["start"]):
            self.state["start"] = t
        if self.params["memory"] == 0.0:
            sx, sy = zx, zy  # not used: the filter is z(t - tau) itself
        else:
            hist = np.vstack((hist, self._filter_jumps(hist[hist[:, 0] < t], t)))
            sx, sy = self._filter(hist[hist[:, 0] < t], t)
        # the oldest time still needed: the next step's outputs look back to t + h - tau,
        # its filter's jumps arrive from jumps after t - tau (the longest delay);
        # keep three samples of the signal before it, for the stencil, so that no
        # lookup from it on changes (first_kept)
        keep = t - self.tau0 - self.params["modulation_amplitude"]
        first = int(first_kept(np.ascontiguousarray(hist, dtype=np.float64), keep))
        self.state["history"] = np.vstack((hist[first:], [[t, zx, zy, sx, sy, SAMPLE]]))

    def _delayed(self, tq: float) -> tuple[float, float]:
        """The fed-back delayed signal: z(tq) (Pyragas) or (1 - R) z(tq) + R S(tq)."""
        hist = self.state["history"]
        before = hist[hist[:, 0] < self.time]
        zx, zy = self._signal()
        sx, sy = (zx, zy) if self.params["memory"] == 0.0 else self._filter(before, self.time)
        v = lookup(np.vstack((before, [[self.time, zx, zy, sx, sy, SAMPLE]])), tq)
        memory = self.params["memory"]
        return etdas_blend(memory, v[0], v[2]), etdas_blend(memory, v[1], v[3])

    def _outputs(self) -> dict[str, float]:
        t = self.time
        tau = self._delay(t)
        if t < self.params["t_on"]:
            return {"ux": 0.0, "uy": 0.0, "current_delay": tau}
        zx, zy = self._signal()
        dx, dy = self._delayed(t - tau)
        gain = self.params["gain"]
        return {
            "ux": feedback_force(gain, zx, dx),
            "uy": feedback_force(gain, zy, dy),
            "current_delay": tau,
        }
