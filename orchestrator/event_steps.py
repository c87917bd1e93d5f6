"""The master's event handling over a macro step: which indicators to watch, whether a
step may cross one, which crossing comes first, and locating it by re-running the step.

A mixin of :class:`.master.Master`; it reads the master's units, outputs and
counters and steps it through ``_step`` and ``_restore``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .cosim_result import CosimError
from .coupling_kernels import secant_offset
from .events import Indicator, crossing, locate, predicted_to_cross
from .protocols import EventProtocol


class EventSteps:
    """Event search and location for a master (see :mod:`.master`)."""

    # --- events ----------------------------------------------------------------------------
    def _indicators(self) -> list[tuple[Indicator, EventProtocol]]:
        if self.settings.events == "off":
            return []
        return [(ind, p) for p in self.protocols for ind in p.indicators(self)]

    def _value(self, ind: Indicator) -> tuple[float, float]:
        out = self.out[ind.unit]
        return out[ind.output], (out[ind.rate] if ind.rate else 0.0)

    def _may_cross(self, inds, h: float) -> bool:
        for ind, _ in inds:
            if ind.rate is None:
                return True  # no rate to predict from: always be ready to roll back
            g, r = self._value(ind)
            key = (ind.unit, ind.output)
            if key not in self.accel or predicted_to_cross(ind, g, r, self.accel[key], h):
                return True
        return False

    def _learn_rates(self, before: Mapping, h: float) -> None:
        """Running bound on the second derivative of every indicator that has a rate."""
        for (unit, output, rate), (_, r0) in before.items():
            if rate is None:
                continue
            r1 = self.out[unit][rate]
            key = (unit, output)
            self.accel[key] = max(self.accel.get(key, 0.0), abs(r1 - r0) / h)

    def _first_crossing(self, inds, before: Mapping, t: float, h: float):
        """The indicator whose crossing inside ``[t, t + h]`` comes first, as
        ``(estimated offset, bracket, indicator, protocol)``, or None."""
        best = None
        for ind, proto in inds:
            ga, ra = before[(ind.unit, ind.output, ind.rate)]
            gb, rb = self._value(ind)
            bracket = crossing(ind, ga, gb, h, ra, rb)
            if bracket is None:
                continue
            est = bracket[0] if bracket[0] > 0.0 else secant_offset(ga, gb, bracket[1])
            if best is None or est < best[0]:
                best = (est, bracket, ind, proto)
        return best

    def _redo(self, t: float, h: float, snap: Any):
        self._restore(snap)
        given, real, _ = self._step(t, h, snap)
        return given, real

    def _locate(self, hit, before, t: float, h: float, snap: Any):
        """Cut the step at the first crossing; returns (h, given, real) with the units
        there, or Nones when a predicted interior crossing is not confirmed."""
        _, (lo, hi), ind, _ = hit
        self._full_h = h
        last = [math.nan]

        def probe(tq: float) -> tuple[float, float]:
            self._restore(snap)
            self._step(t, tq - t, snap)
            last[0] = tq
            self.counters["event_probes"] += 1
            return self._value(ind)

        sign = -1.0 if ind.direction < 0 else 1.0
        ga, ra = before[(ind.unit, ind.output, ind.rate)]
        gb, rb = self._value(ind)  # at t + h: read before a probe moves the units
        if lo > 0.0:
            ga, ra = probe(t + lo)
            if sign * ga >= 0.0:
                return None, None, None
        if hi < h:
            gb, rb = probe(t + hi)
            if sign * gb < 0.0:
                return None, None, None
        t_ev, _ = locate(probe, ind, t + lo, ga, ra, t + hi, gb, rb, self.t_tol)
        if last[0] != t_ev:
            probe(t_ev)
        _, given, real = self._last_round
        return t_ev - t, given, real

    def _event(self, ind: Indicator, proto: EventProtocol) -> None:
        for name in self.left_limit_units:
            self.units[name].do_step(self.time, 0.0)  # it keeps the pre-event inputs
        kind = proto.handle(self, ind)
        self.events.append((self.time, kind, ind.unit))
        self.counters["events"] += 1
        self.counters[f"events_{kind}"] += 1
        real = self.settle()
        self.hist = {k: [(self.time, v)] for k, v in real.items()}
        self.pi.restart()
        self.recent_events.append(self.time)
        while self.recent_events and self.recent_events[0] < self.time - self.period:
            self.recent_events.popleft()
        if len(self.recent_events) > self.settings.max_events_per_period:
            raise CosimError(
                f"{ind.unit}: more than {self.settings.max_events_per_period} events within one "
                f"forcing period before t = {self.time:.9g} s (cosim.max_events_per_period)"
            )
