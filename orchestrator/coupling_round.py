"""One coupling round of the Python master (:class:`.master.Master`): every unit stepped
from ``t`` to ``t + h`` in the coupling order with its inputs as polynomials, then every
input set from its sources' outputs (``settle``); iterated when ``cosim.iterations`` asks.

A mixin: the master holds the units, the connections and their histories.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rubcosim.components.wiring import Connection

from .extrapolation import evaluate, polynomial


class CouplingRounds:
    """Coupling rounds over the master's ``units``, ``order``, ``targets_of``,
    ``source_units``, ``input_orders``, ``hist`` (each input's last communication
    points) and ``out`` (each unit's latest outputs)."""

    def settle(self, fresh: bool = False) -> dict[str, float]:
        """Set every connected input from its sources' current outputs and refresh every
        unit's outputs; returns the input values.

        Units with direct feedthrough come in dependency order, so their sources are
        fresh; the others read from units later in the order, so their inputs are set
        once more at the end (their outputs do not depend on them).  ``fresh``: the
        outputs of units without feedthrough were read since their last change.
        """
        real: dict[str, float] = {}
        for name in self.eval_order:
            if name not in self.out:
                self.out[name] = self.units[name].get_outputs()
        for late in (False, True):
            for name in self.eval_order:
                if late and self.feedthrough[name]:
                    continue
                unit = self.units[name]
                values = {}
                for c in self.targets_of[name]:
                    value = self._sum(c)
                    real[c.target] = value
                    values[c.input] = value
                if values:  # one call per unit: one fmi2SetReal for an FMU
                    unit.set_inputs(values)
                if not late and not (fresh and not self.feedthrough[name]):
                    self.out[name] = unit.get_outputs()
        return real

    def _sum(self, c: Connection) -> float:
        total = 0.0
        out = self.out
        for unit, name in c.pairs:
            total += out[unit][name]
        return total

    def _polynomial(self, c: Connection, t: float, h: float, end: float | None, order: int):
        pts = self.hist[c.target]
        if end is None:
            use = pts[-(order + 1) :]
        else:
            use = (pts[-order:] if order else []) + [(t + h, end)]
        return polynomial(use, t)

    def _round(self, t: float, h: float, ends: Mapping[str, float] | None = None):
        """Step every unit from ``t`` to ``t + h``; returns the input values the units
        were given for ``t + h`` and the values their sources gave there."""
        stepped: set[str] = set()
        given: dict[str, float] = {}
        for name in self.order:
            unit = self.units[name]
            order = self.input_orders[name]
            rows = {}  # input -> (value, d1, d2) at t: set in one call per unit
            for c in self.targets_of[name]:
                end = ends.get(c.target) if ends is not None else None
                if end is None and self.gauss_seidel and self.source_units[c.target] <= stepped:
                    end = self._sum(c)
                v, d1, d2 = self._polynomial(c, t, h, end, order)
                rows[c.input] = (v, d1, d2)
                given[c.target] = evaluate(v, d1, d2, h) if order else v
            if rows and order:
                unit.set_input_polynomials(rows)
            elif rows:
                unit.set_inputs({k: r[0] for k, r in rows.items()})
            unit.do_step(t, h)
            self.counters["unit_steps"] += 1
            stepped.add(name)
            if self.feedthrough[name] and rows:
                # its outputs at t + h follow its inputs there
                unit.set_inputs({c.input: given[c.target] for c in self.targets_of[name]})
            self.out[name] = unit.get_outputs()
        self.time = t + h
        real = self.settle(fresh=True)
        self._last_round = (t + h, given, real)
        return given, real

    def _step(self, t: float, h: float, snap: Any):
        given, real = self._round(t, h)
        err = self._error(given, real, self.settings.rtol)
        for _ in range(1, self.settings.iterations):
            if self._error(given, real, self.settings.iteration_tol) <= 1.0:
                break
            self._restore(snap)
            given, real = self._round(t, h, ends=real)
            self.counters["iterations"] += 1
        return given, real, err
