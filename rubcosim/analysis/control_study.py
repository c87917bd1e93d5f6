"""Chaos control studies: does delayed feedback catch the motion, from when, at what gain?

A study of a scenario with a delayed-feedback controller (``rubcosim
control-study``):

1. the uncontrolled system (the scenario without its controller) and its
   Lyapunov spectrum from the variational equations (:mod:`.lyapunov`);
2. the target: the unstable periodic orbit of period ``delay_periods`` that
   the feedback stabilises (its force vanishes there), found by Newton on the
   stroboscopic map from the closest return of the uncontrolled motion, with its
   Floquet multipliers (:mod:`.floquet`);
3. controlled runs for every gain, memory R and switch-on time: a run has
   converged when its stroboscopic points of the last ``hold`` periods are all
   within ``dist_tol`` state scales of the target's and the control force over
   the last period is below ``force_tol`` times the gain times the fed-back
   signal's scale.  Otherwise it failed, whatever the reason (another orbit,
   chaos, a run that stopped): failures are reported as such.

The controlled runs are delay equations: they run on the ``fast`` engine in
worker processes (:func:`.parallel.executor`), one task per run.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import AnalysisError, MapError
from .floquet import FLOQUET_RTOL, Floquet, floquet, floquet_report
from .lyapunov import Lyapunov, lyapunov_report, lyapunov_spectrum
from .maps import StroboscopicMap

DIST_TOL = 1e-3  # state scales: a strobe point this close to the target's has caught it
FORCE_TOL = 1e-3  # of gain x signal scale: the force has died away
HOLD = 10  # periods: the last strobe points that must all be close


@dataclass(frozen=True)
class ControlRun:
    """One controlled run: ``gain``, ``memory`` (R), ``t_on`` (s); ``converged``; the
    periods from switch-on until the strobe points stay within the distance tolerance
    (-1: never); the strobe points' final distance (state scales) and the largest
    control force over the last period (N); ``status`` of the run ("ok" or why not)."""

    gain: float
    memory: float
    t_on: float
    converged: bool
    periods_to_converge: int
    final_distance: float
    final_force: float
    status: str


@dataclass
class ControlStudy:
    """Everything ``rubcosim control-study`` reports."""

    scenario: str
    period: float  # forcing period T, s
    delay_periods: int
    lyapunov: Lyapunov
    target: Floquet | None
    target_message: str
    runs: list[ControlRun] = field(default_factory=list)

    def success_rates(self) -> dict[tuple[float, float], float]:
        """Share of converged runs per (gain, memory)."""
        out: dict[tuple[float, float], list[bool]] = {}
        for r in self.runs:
            out.setdefault((r.gain, r.memory), []).append(r.converged)
        return {k: float(np.mean(v)) for k, v in out.items()}

    def report(self) -> dict[str, Any]:
        """JSON-able summary."""
        return {
            "scenario": self.scenario,
            "forcing_period_s": self.period,
            "delay_periods": self.delay_periods,
            "uncontrolled_lyapunov": lyapunov_report(self.lyapunov),
            "target": None if self.target is None else _target_report(self.target),
            "target_message": self.target_message,
            "success_rates": [
                {"gain": g, "memory": m, "rate": r}
                for (g, m), r in sorted(self.success_rates().items())
            ],
            "runs": [r.__dict__ for r in self.runs],
        }


def _target_report(f: Floquet) -> dict[str, Any]:
    return {**floquet_report(f), "state": f.state.tolist(), "period": f.period}


def uncontrolled(scenario: Any) -> Any:
    """The scenario without its controller unit (and without outputs naming it)."""
    if "controller" not in scenario.units:
        raise AnalysisError(f"{scenario.name}: the scenario has no [units.controller] to study")
    data = copy.deepcopy(scenario.data)
    data["units"].pop("controller")
    for key in ("plots", "record"):
        table = data.get(key)
        if isinstance(table, dict):
            data[key] = {
                k: [n for n in v if not str(n).startswith("controller.")] for k, v in table.items()
            }
        elif isinstance(table, list):
            data[key] = [n for n in table if not str(n).startswith("controller.")]
    from rubcosim.scenario import build_scenario

    params = {k: v for k, v in scenario.overrides.items() if not k.startswith("controller.")}
    return build_scenario(data, params=params, source=scenario.source)


def find_target(
    smap: StroboscopicMap, points: np.ndarray, modes: np.ndarray, period: int, tries: int = 8
) -> tuple[Floquet | None, str]:
    """The ``period``-periodic orbit nearest the closest returns of ``points`` (strobe
    points of the uncontrolled motion), by Newton; ``(None, why)`` if none converges."""
    n = points.shape[0] - period
    if n < 1:
        raise AnalysisError(f"need more than {period} strobe points to look for a target")
    gaps = np.max(np.abs(points[period:] - points[:-period]) / smap.scale, axis=1)
    why = "no closest return converged"
    for i in np.argsort(gaps)[:tries]:
        try:
            f = floquet(smap, points[i], period, int(modes[i]))
        except (MapError, np.linalg.LinAlgError) as exc:
            why = str(exc)
            continue
        if f.residual < 1e-8:
            return f, f"Newton from the closest return {gaps[i]:.3g} scales (strobe point {i})"
        why = f"Newton stalled at a residual of {f.residual:.3g} scales"
    return None, why


def target_points(f: Floquet, smap: StroboscopicMap) -> np.ndarray:
    """The target orbit's ``period`` strobe points."""
    orbit = smap.orbit(f.state, keep=f.period)
    return np.vstack((f.state, orbit.points[:-1]))


def controlled_run(
    scenario: Any,
    gain: float,
    memory: float,
    t_on: float,
    periods: int,
    target: np.ndarray,
    scale: np.ndarray,
    rtol: float,
) -> dict[str, np.ndarray]:
    """One controlled run (a worker task): ``periods`` forcing periods after ``t_on``."""
    from rubcosim.reference import simulate

    sc = scenario.with_params(
        {"controller.gain": gain, "controller.memory": memory, "controller.t_on": t_on}
    )
    system = sc.system
    T = system.forcing_period
    k_on = math.ceil(t_on / T - 1e-9)
    k_end = k_on + periods
    strobes = np.arange(k_on, k_end + 1) * T
    last = np.linspace((k_end - 1) * T, k_end * T, 41)
    t_eval = np.unique(np.concatenate((strobes, last)))
    res = simulate(system, k_end * T, t_eval=t_eval, engine="fast", rtol=rtol)
    names = system.state_names
    states = np.column_stack([res.output(n) for n in names])
    at = np.searchsorted(t_eval, strobes)
    pts = states[at]
    dist = np.min(np.max(np.abs(pts[:, None, :] - target[None, :, :]) / scale, axis=2), axis=1)
    force = np.hypot(res.output("controller.ux"), res.output("controller.uy"))
    tail = np.searchsorted(t_eval, last)
    return {
        "distance": dist,
        "force": np.array([np.nanmax(force[tail]) if res.ok else math.nan]),
        "ok": np.array([res.ok]),
        "message": np.array([res.message]),
    }


def judge(
    gain: float,
    memory: float,
    t_on: float,
    result: dict[str, np.ndarray],
    signal_scale: float,
    hold: int = HOLD,
    dist_tol: float = DIST_TOL,
    force_tol: float = FORCE_TOL,
) -> ControlRun:
    """A run's verdict from its strobe distances and final force (see the module doc)."""
    dist = result["distance"]
    ok = bool(result["ok"][0])
    force = float(result["force"][0])
    close = np.isfinite(dist) & (dist < dist_tol)
    # the first strobe after which every point stays close
    far = np.flatnonzero(~close)
    first = int(far[-1] + 1) if far.size else 0
    settled = ok and first < close.size and close.size - first >= hold
    small = force < force_tol * abs(gain) * signal_scale
    converged = bool(settled and small)
    return ControlRun(
        gain=float(gain),
        memory=float(memory),
        t_on=float(t_on),
        converged=converged,
        periods_to_converge=first if settled else -1,
        final_distance=float(dist[-1]) if dist.size else math.nan,
        final_force=force,
        status="ok" if ok else str(result["message"][0]),
    )


def switch_on_times(spec: str | tuple[float, float, int]) -> np.ndarray:
    """``"A:B:N"`` (s): N switch-on times spread evenly over [A, B]."""
    if isinstance(spec, str):
        parts = spec.split(":")
        if len(parts) != 3:
            raise AnalysisError(f"--switch-on {spec!r}: expected A:B:N (s, s, count)")
        try:
            a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
        except ValueError:
            raise AnalysisError(f"--switch-on {spec!r}: expected A:B:N (s, s, count)") from None
    else:
        a, b, n = float(spec[0]), float(spec[1]), int(spec[2])
    if not (0.0 <= a <= b and n >= 1 and math.isfinite(b)):
        raise AnalysisError(f"--switch-on {spec!r}: needs 0 <= A <= B and N >= 1")
    return np.linspace(a, b, n) if n > 1 else np.array([a])


def run_control_study(
    scenario: Any,
    switch_on: str | tuple[float, float, int],
    gains: list[float] | None = None,
    memories: list[float] | None = None,
    *,
    periods: int = 200,
    lyapunov_periods: int = 500,
    transient: int = 200,
    rtol: float = 1e-10,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> ControlStudy:
    """The study of the module doc over ``gains`` x ``memories`` (default: the
    scenario's own) x the switch-on times; ``periods`` forcing periods after each
    switch-on; ``lyapunov_periods`` and ``transient`` for the uncontrolled spectrum and
    the strobe points searched for the target."""
    from .parallel import executor, run_tasks

    times = switch_on_times(switch_on)
    ctl = scenario.units.get("controller")
    if ctl is None:
        raise AnalysisError(f"{scenario.name}: the scenario has no [units.controller] to study")
    params = scenario.graph.units["controller"].params
    gains = [float(params["gain"])] if not gains else [float(g) for g in gains]
    memories = [float(params["memory"])] if not memories else [float(m) for m in memories]
    for m in memories:
        if not 0.0 <= m < 1.0:
            raise AnalysisError(f"controller.memory = {m!r} is outside [0, 1)")
    if periods < HOLD + 1:
        raise AnalysisError(f"--periods {periods!r}: must be > {HOLD}")
    if params["delay"] > 0.0 or params["modulation_amplitude"] > 0.0:
        raise AnalysisError(
            "controller.delay, controller.modulation_amplitude: a control study targets the "
            "orbit of period delay_periods; give the delay in periods, unmodulated"
        )
    n = int(params["delay_periods"])
    free = uncontrolled(scenario).system
    lyap = lyapunov_spectrum(free, lyapunov_periods, transient, rtol=min(rtol, 1e-9))
    smap = StroboscopicMap(free, FLOQUET_RTOL)
    orbit = StroboscopicMap(free, rtol).orbit(skip=transient, keep=lyapunov_periods)
    if not orbit.ok:
        raise AnalysisError(f"the uncontrolled run failed: {orbit.message}")
    target, why = find_target(smap, orbit.points, orbit.modes, n)
    study = ControlStudy(scenario.name, free.forcing_period, n, lyap, target, why)
    if target is None:
        return study
    points = target_points(target, smap)
    scale = np.asarray(free.state_scale, dtype=float)
    names = list(free.state_names)
    signal = "rotor.x" if params["feedback"] == "position" else "rotor.vx"
    signal_scale = float(scale[names.index(signal)])
    cases = [(g, m, t) for g in gains for m in memories for t in times]
    tasks = [
        (str(i), (scenario, g, m, t, periods, points, scale, rtol))
        for i, (g, m, t) in enumerate(cases)
    ]
    with executor(workers, scheduler) as pool:
        results = run_tasks(controlled_run, tasks, pool, desc="controlled runs", progress=progress)
    study.runs = [
        judge(g, m, t, results[str(i)], signal_scale) for i, (g, m, t) in enumerate(cases)
    ]
    return study
