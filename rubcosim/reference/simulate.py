"""Run an assembled system with either engine and collect the result."""

from __future__ import annotations

import importlib
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rubcosim.compile_notice import announce
from rubcosim.progress import watch
from rubcosim.timegrid import output_grid

from . import compile_helper
from .assemble import System
from .core import (
    C_EVAL,
    C_EVENTS,
    C_IMPACTS,
    C_REJECTED,
    C_RESTARTS,
    C_RHS,
    C_STATUS,
    C_STEPS,
    N_COUNTERS,
    STATUS_HISTORY_OVERFLOW,
    STATUS_MESSAGES,
    STATUS_OK,
    new_event_log,
)
from .history import (
    HM_OVERFLOW,
    Q_DROPPED,
    new_history,
    new_queue,
    push_arrivals,
)
from .specialize import compiled_model, model_key
from .system import KIND_NAMES

# engine name -> its module (compiled once for every model; the model's own kernels:
# specialize.compiled_model)
ENGINES = {"fast": "rubcosim.reference.fast", "accurate": "rubcosim.reference.accurate"}
# scipy refuses tolerances tighter than 100 machine epsilons.
MIN_RTOL = 100 * np.finfo(float).eps


@dataclass
class Events:
    """Every event in order: time, kind (see ``KIND_NAMES``), slot, mode after, state after."""

    t: np.ndarray
    kind: np.ndarray
    slot: np.ndarray
    mode: np.ndarray
    state: np.ndarray

    def of_kind(self, name: str) -> np.ndarray:
        """Indices of the events of one kind, e.g. ``"impact"``."""
        return np.flatnonzero(self.kind == KIND_NAMES.index(name))


@dataclass
class Result:
    engine: str
    t: np.ndarray
    outputs: np.ndarray
    output_names: list[str]
    events: Events
    status: int
    message: str
    t_reached: float
    final_state: np.ndarray
    final_mode: int
    # steps, rejected_steps (fast engine only: scipy does not expose its
    # rejections), rhs_evaluations, restarts, events, impacts, ...
    counters: dict[str, int] = field(default_factory=dict)
    wall_time_s: float = 0.0  # the integration alone
    warmup_s: float = 0.0  # loading/compiling the engine in this process, if it happened here

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK

    def output(self, name: str) -> np.ndarray:
        """One recorded output by name, e.g. ``"rotor.x"``."""
        return self.outputs[:, self.output_names.index(name)]


_WARM: set[tuple[str, bool]] = set()

# Event logs kept between runs, one per (capacity, states), a few capacities at most.
# A log holds max_events rows (6.4 MB for the default and a rotor); made afresh at
# every run, it is mapped and unmapped by the allocator each time, and each page the
# run writes faults again: 27 us of a rotor run's 40 us of fixed cost, measured.
# A result copies its events out, so the log is free again when simulate returns.
_SPARE_LOGS: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}
_MAX_SPARE_LOGS = 4


def _take_event_log(max_events: int, n_state: int) -> tuple[np.ndarray, ...]:
    # dict.pop is atomic: two threads never get the same log
    log = _SPARE_LOGS.pop((max_events, n_state), None)
    return log if log is not None else new_event_log(max_events, n_state)


def _return_event_log(log: tuple[np.ndarray, ...]) -> None:
    kept = list(_SPARE_LOGS)  # a copy (one C call): another thread may change the dict
    for old in kept[: max(0, len(kept) - _MAX_SPARE_LOGS + 1)]:  # the longest kept
        _SPARE_LOGS.pop(old, None)
    _SPARE_LOGS[(log[0].shape[0], log[4].shape[1])] = log


def _warm_up(
    system: System, engine: str, t_start: float, rtol: float, atol: float, max_step: float
) -> float:
    """Load (or compile) the engine and the model's kernels once per process, outside the
    timed run.  An engine not compiled yet compiles in a second process
    (:mod:`.compile_ahead`) while this one compiles the model's kernels."""
    key = (engine, model_key(system.ip), system.has_delay)
    if key in _WARM:
        return 0.0
    _WARM.add(key)
    t0 = time.perf_counter()
    helper = compile_helper.start(system, engine)
    model = compiled_model(system)  # says so if it compiles
    if helper is not None:
        helper.finish()
    with announce(compile_helper.engine_label(engine, system.has_delay)):
        tiny_run(system, model, engine, t_start, rtol, atol, max_step)
    compile_helper.mark_compiled(engine, system.has_delay)
    return time.perf_counter() - t0


def tiny_run(
    system: System,
    model: tuple,
    engine: str,
    t_start: float,
    rtol: float,
    atol: float,
    max_step: float,
) -> None:
    """A run of a millionth of a forcing period: what compiles (or loads) the engine's
    variant for this model's type."""
    tiny = 1e-6 * system.forcing_period
    t_eval = np.array([t_start + tiny])
    atol_arr = atol * system.state_scale
    _run(system, model, engine, t_start, t_start + tiny, t_eval, (rtol, atol_arr, max_step), 8, 16)


def simulate(
    system: System,
    t_end: float,
    *,
    t_start: float = 0.0,
    t_eval: np.ndarray | None = None,
    output_step: float | None = None,
    engine: str = "fast",
    rtol: float = 1e-10,
    atol: float | None = None,
    max_events: int = 100_000,
    max_step: float = math.inf,
    history_capacity: int = 4096,
    progress: bool = False,
) -> Result:
    """Integrate ``system`` from ``t_start`` to ``t_end``.

    ``atol`` is relative to each state's characteristic size
    (``system.state_scale``: clearance for displacements, clearance times
    speed for velocities); it defaults to ``rtol``.  Outputs are recorded at
    ``t_eval`` (sorted), or on a uniform grid of ``output_step``.  ``progress``: a bar
    in simulated time on a terminal when the run lasts more than a couple of seconds
    (:mod:`rubcosim.progress`).
    """
    if engine not in ENGINES:
        raise ValueError(f"engine = {engine!r} is not one of {', '.join(ENGINES)}")
    if not t_end > t_start:
        raise ValueError(f"sim.t_end = {t_end!r} must be greater than sim.t_start = {t_start!r}")
    if not MIN_RTOL <= rtol < 1.0:
        raise ValueError(f"sim.rtol = {rtol!r} is outside [{MIN_RTOL:.3g}, 1)")
    atol_rel = rtol if atol is None else atol
    if not atol_rel > 0.0:
        raise ValueError(f"sim.atol = {atol!r} must be > 0")
    if t_eval is None:
        step = output_step if output_step is not None else (t_end - t_start) / 1000.0
        t_eval = output_grid(t_start, t_end, step)
    t_eval = np.ascontiguousarray(t_eval, dtype=float)
    max_step = min(max_step, system.min_delay())
    warmup = _warm_up(system, engine, t_start, rtol, atol_rel, max_step)
    model = compiled_model(system)  # loaded by the warm-up
    tol = (rtol, atol_rel * system.state_scale, max_step)
    result = _run(
        system, model, engine, t_start, t_end, t_eval, tol, max_events, history_capacity, progress
    )
    result.warmup_s = warmup
    return result


def _run(
    system: System,
    model: tuple,
    engine: str,
    t_start: float,
    t_end: float,
    t_eval: np.ndarray,
    tol: tuple[float, np.ndarray, float],
    max_events: int,
    history_capacity: int,
    progress: bool = False,
) -> Result:
    """One run of ``engine`` on ``system`` with the model tuple ``model``;
    ``tol = (rtol, atol array, max_step)``."""
    integrate = importlib.import_module(ENGINES[engine]).integrate
    p_vals = np.array(system.p, dtype=float)
    n = system.n_state
    capacity = history_capacity
    evlog = _take_event_log(max_events, n)  # a retry below overwrites it from the start
    while True:
        rec = np.full((t_eval.shape[0], len(system.output_names)), np.nan)
        # No controller, no history: the engines compile a delay-free variant.
        hist = new_history(capacity, t_start, system.y0) if system.has_delay else None
        queue, qmeta = new_queue(capacity if system.has_delay else 1)
        if system.has_delay:
            # the constant initial function meets the motion at t_start with a kink
            # (its derivative is zero): it reaches the delayed term one delay later
            push_arrivals(queue, qmeta, t_start, 1.0, p_vals, model)
        cnt = np.zeros(N_COUNTERS, dtype=np.int64)
        y_final = np.empty(n)
        t0 = time.perf_counter()

        def reached(cnt=cnt, t_eval=t_eval) -> float:
            # the engine writes how many grid points it has recorded (the compiled one
            # runs without the GIL, so this thread reads it while it runs)
            done = int(cnt[C_EVAL])
            return float(t_eval[done - 1]) if 0 < done <= t_eval.shape[0] else t_start

        with watch(f"{engine} engine", t_start, t_end, reached, enabled=progress):
            t_reached, mode = integrate(
                system.y0.copy(),
                system.mode0,
                t_start,
                t_end,
                p_vals,
                model,
                tol,
                (t_eval, rec, evlog, cnt),
                hist,
                (queue, qmeta),
                y_final,
                None,
            )
        wall = time.perf_counter() - t0
        if hist is not None and hist[5][HM_OVERFLOW] and cnt[C_STATUS] == STATUS_OK:
            cnt[C_STATUS] = STATUS_HISTORY_OVERFLOW
        if cnt[C_STATUS] == STATUS_HISTORY_OVERFLOW and capacity < 1 << 22:
            capacity *= 8
            continue
        break
    n_ev = min(int(cnt[C_EVENTS]), max_events)
    events = Events(*(a[:n_ev].copy() for a in evlog))
    _return_event_log(evlog)
    status = int(cnt[C_STATUS])
    message = STATUS_MESSAGES[status]
    if status != STATUS_OK:
        message = f"{message} (t = {t_reached:.9g})"
    return Result(
        engine=engine,
        t=t_eval,
        outputs=rec,
        output_names=list(system.output_names),
        events=events,
        status=status,
        message=message,
        t_reached=float(t_reached),
        final_state=y_final,
        final_mode=int(mode),
        counters={
            "steps": int(cnt[C_STEPS]),
            "rejected_steps": int(cnt[C_REJECTED]),
            "rhs_evaluations": int(cnt[C_RHS]),
            "restarts": int(cnt[C_RESTARTS]),
            "events": int(cnt[C_EVENTS]),
            "impacts": int(cnt[C_IMPACTS]),
            "delay_breakpoints_dropped": int(qmeta[Q_DROPPED]),
        },
        wall_time_s=wall,
    )
