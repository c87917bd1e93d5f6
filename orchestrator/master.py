"""The co-simulation master: steps coupled units, controls the macro step, handles events.

One algorithm, two coupling orders: Gauss-Seidel (a unit sees the outputs its
sources produced in the same step, interpolated) or Jacobi (every unit sees
its inputs extrapolated from the previous communication points).  Inputs are
polynomials of order 0, 1 or 2 over the step (:mod:`.extrapolation`); units
that cannot take input derivatives (an FMU without ``canInterpolateInputs``)
hold them constant.

Per macro step ``[t, t + h]``:

1. a snapshot of every unit is taken when the step may have to be undone:
   error control or iteration is on, or an event indicator is predicted to
   cross within the step (:func:`.events.predicted_to_cross`); otherwise
   only a checkpoint every ``CHECKPOINT_EVERY`` steps, from which the master
   replays (deterministically) if an indicator crossed unannounced;
2. the units are stepped in order, then every input is set to the value its
   sources now give (``settle``); the difference between what a unit was
   given for ``t + h`` and what its sources gave is the coupling error;
3. with error control, a step whose error norm exceeds 1 is undone and
   retried smaller (PI controller, :mod:`.step_control`), unless the error
   comes from a kink or jump in a foreign FMU's output: then the step is cut
   just past it and that input's extrapolation restarts (:mod:`.kink_steps`);
4. the event protocols' indicators are checked for a crossing; one is
   located by re-running the step onto trial times (:func:`.events.locate`),
   the step is cut there, the protocol acts (a velocity reset, a contact
   mode) and the extrapolation restarts from the new values.

Nothing here knows any physics: forces, gaps and impact laws are the units'.
"""

from __future__ import annotations

import math
import time
from collections import Counter, deque
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rubcosim.components.unit import StepError
from rubcosim.components.wiring import Connection
from rubcosim.progress import watch

from .cosim_result import CosimError, CosimResult, fmi_counters
from .coupling_norms import CouplingNorms
from .coupling_round import CouplingRounds
from .event_steps import EventSteps
from .flat_layout import CHECKPOINT_EVERY, STALL_STEPS
from .flat_master import flat_ready, flat_unsupported, run_flat
from .kink_steps import KinkSteps
from .ordering import evaluation_order
from .protocols import EventProtocol
from .recording import Recorder
from .rollback import Rollback
from .settings import CosimSettings
from .step_control import PIController

__all__ = ["CosimError", "CosimResult", "Master", "evaluation_order"]


class Master(CouplingRounds, CouplingNorms, EventSteps, KinkSteps, Rollback):
    """Runs coupled units from ``t_start`` to ``t_end``.

    ``units`` maps a name to a unit (a :class:`rubcosim.components.unit.Unit` or an
    :class:`.fmu_unit.FmuUnit`); ``feedthrough[name]`` says whether its outputs
    depend on its inputs at the same instant; ``interpolates[name]`` whether it
    takes input derivatives.  ``period`` (s) scales the default steps and the
    event tolerance.  ``kink_sources``: units whose outputs may have kinks or jumps they
    do not announce (foreign FMUs), located as events (:mod:`.kink_steps`).
    """

    def __init__(
        self,
        units: Mapping[str, Any],
        connections: Sequence[Connection],
        settings: CosimSettings,
        period: float,
        feedthrough: Mapping[str, bool],
        interpolates: Mapping[str, bool],
        protocols: Sequence[EventProtocol] = (),
        left_limits: Sequence[str] = (),
        nominal: Mapping[str, float] | None = None,
        bounds: Mapping[str, float] | None = None,
        kink_sources: Sequence[str] = (),
    ) -> None:
        self.units = dict(units)
        self.settings = settings.with_defaults(period)
        self.period = period
        self.connections = list(connections)
        self.protocols = list(protocols)
        self.left_limit_units = list(left_limits)
        self.nominal = dict(nominal or {})
        # |value| past which a connection means the run diverged (e.g. a displacement of
        # a hundred clearances)
        self.bounds = dict(bounds or {})
        self.source_of = {c.target: c.sources for c in connections}
        self.feedthrough = dict(feedthrough)
        self.eval_order = evaluation_order(list(self.units), self.connections, feedthrough)
        order = list(self.settings.order) or self.eval_order
        if sorted(order) != sorted(self.units):
            raise CosimError(
                f"cosim.order = {order} must name every unit once ({', '.join(self.units)})"
            )
        self.order = order
        self.targets_of: dict[str, list[Connection]] = {n: [] for n in self.units}
        for c in self.connections:
            self.targets_of[c.unit].append(c)
        self.source_units = {c.target: {s.split(".", 1)[0] for s in c.sources} for c in connections}
        locate_kinks = self.settings.kinks == "locate" and self.settings.adaptive
        self.kink_inputs = self._kink_inputs(set(kink_sources)) if locate_kinks else set()
        p = self.settings.extrapolation
        self.input_orders = {n: (p if interpolates[n] else 0) for n in self.units}
        self.gauss_seidel = self.settings.algorithm == "gauss-seidel"
        self.t_tol = self.settings.event_tol * period
        self.counters: Counter[str] = Counter()
        self.time = 0.0
        self.out: dict[str, dict[str, Any]] = {}
        self._last_round: tuple[float, dict, dict] | None = None

    # --- what protocols may call --------------------------------------------------------
    def set_event_input(self, unit: str, name: str, value: float) -> None:
        self.units[unit].set_input(name, value)

    def apply_now(self, unit: str) -> None:
        """A zero-length step: the unit applies what was just set (a reset) at once."""
        self.units[unit].do_step(self.time, 0.0)

    # --- the run ---------------------------------------------------------------------------
    def run(
        self,
        t_start: float,
        t_end: float,
        output_times: np.ndarray,
        record: Sequence[str],
        progress: bool = False,
    ) -> CosimResult:
        """Co-simulate from ``t_start`` to ``t_end`` recording ``record`` (``unit.output``)
        at ``output_times``; a failure ends the run early with ``status = "failed"``.
        ``progress``: a bar in simulated time on a terminal for runs of more than a couple
        of seconds."""
        if self.settings.master != "python":
            why = flat_unsupported(self)
            if why is None and flat_ready(self.settings.master):
                return run_flat(self, t_start, t_end, output_times, list(record), progress)
            if self.settings.master == "compiled":
                raise CosimError(f"cosim.master = 'compiled': {why}; use 'auto' or 'python'")
        wall = time.perf_counter()
        st = self.settings
        self.time = float(t_start)
        self.h = st.step
        p = st.extrapolation if st.adaptive else 0
        self.pi = PIController(order=p + 1)
        self.accel: dict[tuple[str, str], float] = {}
        self.events: list[tuple[float, str, str]] = []
        self.recent_events: deque[float] = deque()
        self.recorder = Recorder(record, self.units)
        self.output_times = np.asarray(output_times, dtype=float)
        self.k_out = 0
        status, message = "ok", ""
        try:
            real = self.settle()
            self.hist = {k: [(self.time, v)] for k, v in real.items()}
            self.scale = {k: max(abs(v), self.nominal.get(k, 0.0)) for k, v in real.items()}
            self._record_due()
            with watch("co-simulation", t_start, t_end, lambda: self.time, enabled=progress):
                self._loop(t_end)
        except (CosimError, StepError) as exc:
            status, message = "failed", str(exc)
        n = len(self.output_times[: len(self.recorder)])
        names, values, texts = self.recorder.arrays(n)
        return CosimResult(
            t=self.output_times[:n].copy(),
            names=names,
            values=values,
            texts=texts,
            event_t=np.array([e[0] for e in self.events]),
            event_kind=[e[1] for e in self.events],
            event_unit=[e[2] for e in self.events],
            counters={**self.counters, **fmi_counters(self.units.values())},
            status=status,
            message=message,
            t_reached=self.time,
            wall_time_s=time.perf_counter() - wall,
            settings=st,
            input_orders=dict(self.input_orders),
        )

    def _record_due(self) -> None:
        tol = 1e-9 * self.settings.min_step
        while (
            self.k_out < len(self.output_times) and self.output_times[self.k_out] <= self.time + tol
        ):
            self.recorder.take(self.out, self.units)
            self.k_out += 1

    def _loop(self, t_end: float) -> None:
        st = self.settings
        checkpoint = (self._snapshot(), self._master_state())
        since_checkpoint = 0
        snap_until = -math.inf
        at_floor = 0
        while self.time < t_end:
            t = self.time
            target = t_end
            if self.k_out < len(self.output_times):
                target = min(target, self.output_times[self.k_out])
            h_nominal = min(self.h, st.max_step)
            h = h_nominal
            if t + h >= target - 1e-9 * h:
                h = target - t
            inds = self._indicators()
            snap = None
            if st.adaptive or st.iterations > 1 or t < snap_until or self._may_cross(inds, h):
                snap = self._snapshot()
            elif since_checkpoint >= CHECKPOINT_EVERY:
                self._free(checkpoint[0])
                checkpoint = (self._snapshot(), self._master_state())
                since_checkpoint = 0
            before = {(i.unit, i.output, i.rate): self._value(i) for i, _ in inds}
            self.counters["steps"] += 1
            try:
                given, real, err = self._step(t, h, snap)
            except StepError as exc:
                if snap is None or h <= st.min_step:
                    raise CosimError(f"{exc} (macro step {h:.3g} s)") from exc
                self._restore(snap)
                self._set_time(t)
                self._free(snap)
                self.counters["rejected"] += 1
                self.h = h / 4.0
                continue
            kink = None
            if st.adaptive and err > 1.0 and h > st.min_step:
                kink = self._kink_search(t, h, snap, given, real, err) if self.kink_inputs else None
                if kink is None:
                    self._restore(snap)
                    self._set_time(t)
                    self._free(snap)
                    self.counters["rejected"] += 1
                    self.h = max(self.pi.reject(h, err), st.min_step)
                    continue
                h, given, real, err, restart, h_next = kink
            hit = self._first_crossing(inds, before, t, h) if inds else None
            if hit is not None and snap is None and st.events == "locate":
                # an unannounced crossing: replay deterministically from the checkpoint
                self._restore(checkpoint[0])
                self._set_master_state(checkpoint[1])
                snap_until = t + h
                self.counters["replays"] += 1
                continue
            if hit is not None and st.events == "locate":
                h, given, real = self._locate(hit, before, t, h, snap)
                if h is None:  # an interior extremum that did not reach zero after all
                    hit = None
                    given, real = self._redo(t, self._full_h, snap)
                    h = self._full_h
            elif hit is not None and hit[1] != (0.0, h):
                hit = None  # a plain master only sees sign changes at communication points
            self._accept(t, h, given, real, before)
            if kink is not None and hit is None:
                if restart:
                    self._restart_inputs(restart, real)
                self.h = min(h_next or h, st.max_step)
            elif st.adaptive and hit is None and h >= 0.5 * h_nominal:
                self.h = min(max(self.pi.accept(h_nominal, err), st.min_step), st.max_step)
            # accepted only because the step could not shrink further
            at_floor = at_floor + 1 if st.adaptive and err > 1.0 else 0
            if at_floor > STALL_STEPS:
                raise CosimError(
                    f"the coupling error stayed above cosim.rtol at cosim.min_step = "
                    f"{st.min_step:.3g} s for {STALL_STEPS} steps before t = {self.time:.9g} s; "
                    f"the largest is on {self._worst(given, real)}"
                )
            self._free(snap)
            since_checkpoint += 1
            if hit is not None:
                self._event(hit[2], hit[3])
            for proto in self.protocols if st.events != "off" else ():
                late = proto.overdue(self)
                if late is not None:
                    self.counters["late_events"] += 1
                    self._event(late, proto)
            self._check_finite()
            self._record_due()
        self._free(checkpoint[0])

    def _set_time(self, t: float) -> None:
        self.time = t
        for name, unit in self.units.items():
            self.out[name] = unit.get_outputs()

    def _accept(self, t: float, h: float, given, real, before) -> None:
        self.time = t + h
        for key, value in real.items():
            pts = self.hist[key]
            pts.append((self.time, value))
            if len(pts) > 3:
                del pts[0]
            self.scale[key] = max(self.scale[key], abs(value))
        if h > 0.0:
            self._learn_rates(before, h)
        self.counters["accepted"] += 1

    def _check_finite(self) -> None:
        for name, out in self.out.items():
            for key, value in out.items():
                if not math.isfinite(value):
                    raise CosimError(f"{name}.{key} = {value} at t = {self.time:.9g} s")
        for target, bound in self.bounds.items():
            value = self.hist[target][-1][1]
            if abs(value) > bound:
                sources = " + ".join(self.source_of[target])
                raise CosimError(
                    f"unstable: {sources} = {value:.3g} passed {bound:.3g} at t = "
                    f"{self.time:.9g} s; the coupled model diverges (if the monolithic "
                    "engines diverge too, the model itself is unstable)"
                )
