"""Kinks and jumps in a foreign FMU's outputs, located like events.

A foreign FMU may have events of its own that it does not announce: a bouncing
ball's height has a kink at every bounce, its velocity a jump.  An input
polynomial built across such a point is wrong by the kink's slope change times
the time since it, whatever the step; error control alone shrinks the step onto
the kink from below again and again, then again after it until the history no
longer straddles it (tens of thousands of rejections on a bouncing ball).

The master treats it as an event instead.  A step whose coupling error on an
input fed by such a unit exceeds ``SURPRISE`` (the PI controller aims at about
1, so this is not a step that was merely too long) is cut by probing shorter
steps from the same snapshot: past the kink the deviation of the source from
the polynomial grows linearly, so two probes past it give the line and the
next probe lands where the deviation is half the tolerance, just past the kink.
A jump (no acceptable point past it) is bracketed to the event tolerance and
the step ends just past it.  The step is accepted there and that input's
extrapolation restarts from the new value (its history held only points before
the kink), with a first step sized from the slope after the kink.

A kink is told from an ordinary large error by how fast the error rises across
the final bracket: like ``s^(p+1)`` for a smooth signal, abruptly at a kink.
A search that finds no kink counts as a rejected step and the step found is
taken, as a retry would be.  Counters: ``kinks`` located, ``kink_probes``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

# coupling error (in tolerances) past which a rejected step is searched for a kink
SURPRISE = 10.0
# the error must rise across the final bracket at least this many times faster (in
# log-log slope) than a smooth signal's error (order p + 1) to count as a kink
KINK_STEEPNESS = 2.0
MAX_KINK_PROBES = 60


class KinkSteps:
    """Kink location for a master (see :mod:`.master`): a mixin that steps it through
    ``_step`` and ``_restore`` and reads its history, scales and counters."""

    def _kink_inputs(self, sources: set[str]) -> set[str]:
        """The inputs (``unit.input``) with a source among the units ``sources``."""
        return {t for t, units in self.source_units.items() if units & sources}

    def _kink_search(self, t: float, h: float, snap: Any, given, real, err: float):
        """A rejected step ``[t, t + h]`` with error ``err``: when the worst input is fed
        by a unit with unannounced kinks and the error is a surprise, cut the step past
        the kink.  Returns ``(h, given, real, err, restart, h_next)`` with the units at
        the new step's end, ``restart`` the inputs whose extrapolation restarts there
        (empty when no kink was found), or None for an ordinary rejection."""
        if err < SURPRISE:
            return None
        key = self._worst(given, real)
        if key not in self.kink_inputs:
            return None
        probes = {h: (given, real, err)}
        post = [(h, self._deviation(key, given, real), real[key])]  # past the kink
        lo, hi, s = 0.0, h, h  # the units stand at t + s
        done = False
        for _ in range(MAX_KINK_PROBES):
            if hi - lo <= self.t_tol:
                break
            s = _past_kink(post, lo, hi)
            self._restore(snap)
            g, r, e = self._step(t, s, snap)
            self.counters["kink_probes"] += 1
            probes[s] = (g, r, e)
            d = self._deviation(key, g, r)
            if e <= 1.0:
                lo = s
                if abs(d) >= 0.25:  # on the line past the kink, within the tolerance
                    done = True
                    break
            else:
                hi = s
                post.append((s, d, r[key]))
                post.sort()
        if lo == 0.0 and not done and hi - lo > self.t_tol:
            return None  # nothing acceptable found: an ordinary rejection
        p = self.pi.order
        e_lo = probes[lo][2] if lo > 0.0 else 0.0
        e_hi = probes[hi][2]
        jump = not done and hi - lo <= self.t_tol
        kink = jump or (
            e_lo > 0.0 and math.log(e_hi / e_lo) > KINK_STEEPNESS * p * math.log(hi / lo)
        )
        end = hi if jump else lo
        if end != s:  # the units must stand at the end of the step taken
            self._restore(snap)
            self._step(t, end, snap)
            self.counters["kink_probes"] += 1
        g, r, e = probes[end]
        if not kink:
            self.counters["rejected"] += 1
            return end, g, r, e, (), None
        # the first step after the kink holds the input constant: size it from the slope
        after = [(s_, v) for s_, _, v in post if s_ > end]
        if len(after) >= 2 and after[1][0] > after[0][0]:
            slope = abs((after[1][1] - after[0][1]) / (after[1][0] - after[0][0]))
            scale = max(self.scale[key], abs(r[key]))
            h_next = 0.5 * self.settings.rtol * scale / slope if slope > 0.0 else hi - lo
        else:
            h_next = hi - lo
        return end, g, r, e, self._kink_group(key), max(h_next, self.settings.min_step)

    def _kink_group(self, key: str) -> tuple[str, ...]:
        """The inputs fed by the same units as ``key``: they restart together."""
        units = self.source_units[key]
        return tuple(k for k in self.kink_inputs if self.source_units[k] & units)

    def _restart_inputs(self, keys: tuple[str, ...], real: Mapping[str, float]) -> None:
        for key in keys:
            self.hist[key] = [(self.time, real[key])]
        self.pi.restart()
        self.counters["kinks"] += 1


def _past_kink(post: list[tuple[float, float, float]], lo: float, hi: float) -> float:
    """The next probe: where the line through the two nearest points past the kink puts
    the deviation at half the tolerance, when that lies inside ``(lo, hi)``; else the
    middle of the bracket."""
    if len(post) >= 2:
        (s1, d1, _), (s2, d2, _) = post[0], post[1]
        if s2 > s1 and d1 * d2 > 0.0 and d1 != d2:
            slope = (d2 - d1) / (s2 - s1)
            s_kink = s1 - d1 / slope
            s = s_kink + math.copysign(0.5, d1) / slope
            margin = 1e-3 * (hi - lo)
            if lo + margin < s < hi - margin:
                return s
    return 0.5 * (lo + hi)
