"""Bifurcation diagrams: stroboscopic points against a parameter, by continuation.

Each parameter value starts from the state (and discrete mode) the previous
value ended in, at forcing phase 0, so coexisting motions show as hysteresis
between an upward and a downward sweep.  A value runs ``discard`` periods of
transient, then keeps ``periods`` stroboscopic points and the impacts of
each period.  The values of one direction are a chain of blocks; each block
is a task (one compiled map run per value), its result checkpointed, and the
next block starts from its last state.  Two directions run in parallel.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rubcosim.reference.assemble import System
from rubcosim.scenario import Scenario, ScenarioError

from .errors import AnalysisError
from .maps import DEFAULT_MAX_EVENTS, DEFAULT_RTOL, StroboscopicMap
from .motion import DEFAULT_TOL, classify
from .parallel import Checkpoint, executor, run_tasks

DIRECTIONS = ("up", "down", "both")
DEFAULT_BLOCK = 20  # parameter values per task
SECTION_PER_PERIOD = 4  # impact-section phases kept per kept period (NaN-padded)
_RANGE = re.compile(r"^\s*([^=\s]+)\s*=\s*([^:]+):([^:]+):([^:]+)\s*$")


@dataclass(frozen=True)
class ParamRange:
    """``unit.param=start:stop:count``: ``count`` values from start to stop inclusive."""

    name: str
    start: float
    stop: float
    count: int

    @property
    def values(self) -> np.ndarray:
        return np.linspace(self.start, self.stop, self.count)


def parse_param(text: str) -> ParamRange:
    """Read ``--param unit.param=start:stop:count`` (errors quote the flag)."""
    match = _RANGE.match(text)
    if not match:
        raise ScenarioError(f"--param {text!r}: expected unit.param=start:stop:count")
    name, a, b, n = match.groups()
    if name.count(".") != 1 or not all(name.split(".")):
        raise ScenarioError(f"--param {text!r}: expected unit.param=start:stop:count")
    try:
        start, stop = float(a), float(b)
        count = int(n)
    except ValueError:
        raise ScenarioError(
            f"--param {text!r}: start and stop must be numbers, count an integer"
        ) from None
    if not (math.isfinite(start) and math.isfinite(stop)) or count < 2 or start == stop:
        raise ScenarioError(f"--param {text!r}: needs finite start != stop and count >= 2")
    return ParamRange(name, start, stop, count)


def sweep_values(param: ParamRange | str, values: Any = None) -> tuple[ParamRange, np.ndarray]:
    """The swept parameter and its values: a :class:`ParamRange`, or a name
    (``"rotor.speed"``) with ``values`` (the parameter's unit, e.g. rad/s)."""
    if isinstance(param, ParamRange):
        if values is not None:
            raise AnalysisError(f"{param.name}: give a ParamRange or values, not both")
        return param, param.values
    if not isinstance(param, str) or param.count(".") != 1 or not all(param.split(".")):
        raise ScenarioError(f"--param {param!r}: expected unit.param")
    vals = np.asarray(values if values is not None else [], dtype=float).ravel()
    if vals.size < 2 or not np.all(np.isfinite(vals)):
        raise AnalysisError(f"{param}: the sweep needs at least two finite values")
    return ParamRange(param, float(vals[0]), float(vals[-1]), int(vals.size)), vals


def sweep_systems(scenario: Scenario, param: ParamRange | str, values: Any) -> list[System]:
    """The scenario's system at every value, every override it was loaded with kept
    (each validated: a value out of the parameter's range is an error naming it)."""
    name = param.name if isinstance(param, ParamRange) else param
    systems = [scenario.with_params({name: float(v)}).system for v in values]
    ips = {tuple(s.ip) for s in systems}
    if len(ips) != 1:
        raise ScenarioError(f"--param {name}: changes the model's structure, not a value")
    return systems


def run_block(
    systems: list[Any],
    y0: np.ndarray,
    mode0: int,
    periods: int,
    discard: int,
    rtol: float,
    max_events: int,
) -> dict[str, np.ndarray]:
    """One task: a block of parameter values by continuation from ``(y0, mode0)``."""
    n = y0.size
    pts = np.full((len(systems), periods, n), np.nan)
    imp = np.zeros((len(systems), periods), dtype=np.int64)
    modes = np.zeros((len(systems), periods), dtype=np.int64)
    phases = np.full((len(systems), SECTION_PER_PERIOD * periods), np.nan)
    status = np.zeros(len(systems), dtype=np.int64)
    y, mode = y0.copy(), int(mode0)
    for i, system in enumerate(systems):
        orbit = StroboscopicMap(system, rtol, max_events).orbit(
            y, skip=discard, keep=periods, mode=mode, max_section=phases.shape[1]
        )
        status[i] = orbit.status
        if orbit.ok:
            pts[i], imp[i], modes[i] = orbit.points, orbit.impacts, orbit.modes
            phases[i, : orbit.impact_phases.size] = orbit.impact_phases
            y, mode = orbit.final_state.copy(), orbit.mode
        # a failed value leaves the continuation at the last good state
    return {
        "points": pts,
        "impacts": imp,
        "modes": modes,
        "phases": phases,
        "status": status,
        "y": y,
        "mode": np.array(mode),
    }


@dataclass
class SweepResult:
    """Per direction: ``points[i, k]`` the k-th kept stroboscopic state at ``values[i]``."""

    param: ParamRange
    values: np.ndarray
    state_names: list[str]
    scale: np.ndarray
    periods: int
    discard: int
    points: dict[str, np.ndarray]
    impacts: dict[str, np.ndarray]
    modes: dict[str, np.ndarray]
    status: dict[str, np.ndarray]
    # impact section: forcing phase (rad) of each impact in the kept periods, NaN-padded
    impact_phase: dict[str, np.ndarray]
    # per direction and value: Floquet multipliers (rubcosim.analysis.floquet.sweep_floquet)
    multipliers: dict[str, list[dict[str, Any] | None]] = field(default_factory=dict)
    # per direction and value: largest Lyapunov exponent, 1/s (.lyapunov.sweep_lyapunov)
    lyapunov: dict[str, list[float | None]] = field(default_factory=dict)
    # located grazings (rubcosim.analysis.grazing.sweep_grazings), as dicts
    grazings: list[dict[str, Any]] = field(default_factory=list)

    @property
    def failed(self) -> dict[str, int]:
        """Per direction: the number of values whose integration failed."""
        return {d: int((s != 0).sum()) for d, s in self.status.items()}

    def classify(self, direction: str, tol: float = DEFAULT_TOL) -> list[dict[str, Any]]:
        """Per value: the n-m label and the number of distinct stroboscopic points."""
        out = []
        for i, v in enumerate(self.values):
            if self.status[direction][i] != 0:
                out.append({"value": float(v), "label": "failed", "distinct": 0})
                continue
            m = classify(self.points[direction][i], self.impacts[direction][i], self.scale, tol)
            out.append(
                {
                    "value": float(v),
                    "label": m.label,
                    "period": m.period,
                    "impacts": m.impacts,
                    "distinct": m.distinct,
                    # sustained contact (full rub) or sticking at the section
                    "contact": bool(np.any(self.modes[direction][i] != 0)),
                }
            )
        return out


def sweep(
    scenario: Scenario,
    param: ParamRange | str,
    values: Any = None,
    *,
    periods: int = 100,
    discard: int = 200,
    direction: str = "up",
    rtol: float = DEFAULT_RTOL,
    max_events: int = DEFAULT_MAX_EVENTS,
    workers: int | None = None,
    scheduler: str | None = None,
    checkpoint_dir: Any = None,
    block: int = DEFAULT_BLOCK,
    chains: int = 1,
    progress: bool = False,
) -> SweepResult:
    """Sweep ``param`` (a :class:`ParamRange`, or a name such as ``"rotor.speed"`` with
    ``values`` in the parameter's unit) from the scenario's initial state, every
    override the scenario was loaded with kept.  ``periods`` stroboscopic points are
    kept per value after ``discard`` forcing periods of transient.

    ``chains > 1`` cuts each direction's range into that many parts, each continued
    from the scenario's initial state, so they run in parallel (a hysteresis
    branch may then switch at a part's start).
    """
    if direction not in DIRECTIONS:
        raise AnalysisError(f"--direction {direction!r} is not one of {', '.join(DIRECTIONS)}")
    for flag, v, low in (
        ("--periods", periods, 2),
        ("--discard", discard, 0),
        ("--chains", chains, 1),
        ("block", block, 1),
    ):
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            raise AnalysisError(f"{flag} = {v!r} must be an integer >= {low}")
    param, values = sweep_values(param, values)
    systems = sweep_systems(scenario, param, values)
    # refuses delay systems and a bad rtol up front; loads the kernel before workers fork
    StroboscopicMap(systems[0], rtol, max_events).orbit(keep=1)
    dirs = ["up", "down"] if direction == "both" else [direction]
    # a chain: values run by continuation, cut into blocks (tasks); "chains" cuts each
    # direction's range into that many independent chains (parallel, each from y0)
    chain_blocks: dict[str, list[np.ndarray]] = {}
    for d in dirs:
        order = np.arange(values.size)[:: 1 if d == "up" else -1]
        for c, part in enumerate(np.array_split(order, chains)):
            chain_blocks[f"{d}{c}"] = [part[i : i + block] for i in range(0, part.size, block)]

    def key(chain: str, b: int) -> str:
        return f"{chain}_{b:05d}"

    def task(chain: str, b: int, y: np.ndarray, mode: int) -> tuple[str, tuple[Any, ...]]:
        chunk = [systems[i] for i in chain_blocks[chain][b]]
        return key(chain, b), (chunk, y, mode, periods, discard, rtol, max_events)

    checkpoint = None
    results: dict[str, dict[str, np.ndarray]] = {}
    if checkpoint_dir is not None:
        spec = {
            "analysis": "sweep",
            "scenario": scenario.source or scenario.name,
            "overrides": {k: repr(v) for k, v in scenario.overrides.items()},
            "param": [param.name, *values.tolist()],
            "periods": periods,
            "discard": discard,
            "rtol": rtol,
            "block": block,
            "chains": chains,
            "y0": scenario.system.y0.tolist(),
            "p": [s.p.tolist() for s in systems],
        }
        checkpoint = Checkpoint(checkpoint_dir, spec)
        results = {k: checkpoint.load(k) for k in checkpoint.done()}
    tasks = []
    for chain, chunks in chain_blocks.items():
        b = 0
        while key(chain, b) in results:
            b += 1
        if b < len(chunks):
            prev = results.get(key(chain, b - 1))
            y = scenario.system.y0 if prev is None else prev["y"]
            mode = scenario.system.mode0 if prev is None else int(prev["mode"])
            tasks.append(task(chain, b, y, mode))

    def follow_up(k: str, result: dict[str, np.ndarray]) -> tuple[str, tuple[Any, ...]] | None:
        chain, b = k.split("_")
        nxt = int(b) + 1
        if nxt == len(chain_blocks[chain]):
            return None
        return task(chain, nxt, result["y"], int(result["mode"]))

    if tasks:
        remaining = sum(len(b) for b in chain_blocks.values()) - len(results)
        with executor(workers, scheduler) as pool:
            results.update(
                run_tasks(
                    run_block, tasks, pool, checkpoint, follow_up, remaining, "sweep", progress
                )
            )
    n = scenario.system.n_state
    points, impacts, modes, status, phase = {}, {}, {}, {}, {}
    for d in dirs:
        pts = np.full((values.size, periods, n), np.nan)
        imp = np.zeros((values.size, periods), dtype=np.int64)
        md = np.zeros((values.size, periods), dtype=np.int64)
        ph = np.full((values.size, SECTION_PER_PERIOD * periods), np.nan)
        st = np.zeros(values.size, dtype=np.int64)
        for chain, chunks in chain_blocks.items():
            if chain.startswith(d):
                for b, idx in enumerate(chunks):
                    r = results[key(chain, b)]
                    pts[idx], imp[idx], st[idx] = r["points"], r["impacts"], r["status"]
                    md[idx], ph[idx] = r["modes"], r["phases"]
        points[d], impacts[d], modes[d], status[d], phase[d] = pts, imp, md, st, ph
    return SweepResult(
        param,
        values,
        list(scenario.system.state_names),
        np.asarray(scenario.system.state_scale, dtype=float),
        periods,
        discard,
        points,
        impacts,
        modes,
        status,
        phase,
    )
