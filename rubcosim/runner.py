"""Run a scenario with a monolithic engine or co-simulate it, and its ``report.json``.

Writing the results (``results.csv``, plots) is :mod:`rubcosim.writing`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rubcosim.reference.simulate import Result, output_grid, simulate
from rubcosim.reference.system import KIND_NAMES

from .scenario import Scenario, ScenarioError
from .timegrid import strobe_times

__all__ = [
    "CosimRun",
    "ScenarioRun",
    "report",
    "run_cosim_scenario",
    "run_scenario",
    "strobe_times",
]


@dataclass
class ScenarioRun:
    scenario: Scenario
    result: Result
    grid_rows: np.ndarray  # rows of result that belong to the output grid
    strobe_rows: np.ndarray  # rows that are stroboscopic Poincare samples

    def series(self, name: str) -> np.ndarray:
        return self.result.output(name)[self.grid_rows]

    @property
    def time(self) -> np.ndarray:
        return self.result.t[self.grid_rows]

    def poincare(self, name: str) -> np.ndarray:
        values = self.result.output(name)[self.strobe_rows]
        return values[np.isfinite(values)]


@dataclass
class CosimRun:
    """A co-simulation of a scenario, recorded on the same times as a :class:`ScenarioRun`."""

    scenario: Scenario
    result: Any  # rubcosim.orchestrator.master.CosimResult
    grid_rows: np.ndarray
    strobe_rows: np.ndarray

    def _rows(self, rows: np.ndarray) -> np.ndarray:
        return rows[rows < self.result.t.size]

    def series(self, name: str) -> np.ndarray:
        return self.result.output(name)[self._rows(self.grid_rows)]

    @property
    def time(self) -> np.ndarray:
        return self.result.t[self._rows(self.grid_rows)]

    def poincare(self, name: str) -> np.ndarray:
        return self.result.output(name)[self._rows(self.strobe_rows)]


def run_cosim_scenario(
    scenario: Scenario, backend: str | None = None, progress: bool = False
) -> CosimRun:
    """Co-simulate a scenario with its ``[cosim]`` settings (``backend`` overrides);
    ``progress``: a bar in simulated time on a terminal for long runs."""
    from dataclasses import replace

    from rubcosim.orchestrator.assembly import run_cosim
    from rubcosim.timegrid import output_times

    settings = scenario.cosim if backend is None else replace(scenario.cosim, backend=backend)
    times, grid_rows, strobe_rows = output_times(scenario)
    result = run_cosim(scenario, settings, times=times, progress=progress)
    return CosimRun(scenario, result, grid_rows, strobe_rows)


def cosim_report(run: CosimRun) -> dict[str, Any]:
    r, sc = run.result, run.scenario
    return {
        "scenario": sc.name,
        "description": sc.description,
        "source": sc.source,
        "engine": r.engine,
        "master": r.master,
        "status": r.status,
        "message": r.message,
        "t_start": sc.sim["t_start"],
        "t_end": sc.sim["t_end"],
        "t_reached": r.t_reached,
        "wall_time_s": r.wall_time_s,
        "n_events": int(r.counters.get("events", 0)),
        "n_impacts": int(r.counters.get("events_impact", 0)),
        "counters": r.counters,
        "cosim_settings": {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(r.settings).items()
        },
        "input_orders": r.input_orders,
        "forcing_period": sc.system.forcing_period,
        "poincare_points": int(run._rows(run.strobe_rows).size),
        "parameters": dict(sc.parameters),
        "outputs": sc.outputs,
    }


def run_scenario(
    scenario: Scenario, engine: str | None = None, progress: bool = False
) -> ScenarioRun:
    if scenario.fmus:
        name = next(iter(scenario.fmus))
        raise ScenarioError(
            f"fmus.{name}: the monolithic engines cannot simulate a foreign FMU; run the "
            "scenario as a co-simulation (rubcosim run --backend direct or fmu)"
        )
    sim = scenario.sim
    step = sim["output_step"] or (sim["t_end"] - sim["t_start"]) / 1000.0
    grid = output_grid(sim["t_start"], sim["t_end"], step)
    strobe = strobe_times(scenario)
    t_all = np.concatenate((grid, strobe))
    order = np.argsort(t_all, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    result = simulate(
        scenario.system,
        sim["t_end"],
        t_start=sim["t_start"],
        t_eval=t_all[order],
        engine=engine or sim["engine"],
        rtol=sim["rtol"],
        atol=sim["atol"],
        max_events=sim["max_events"],
        progress=progress,
    )
    return ScenarioRun(scenario, result, rank[: grid.size], rank[grid.size :])


def report(run: ScenarioRun | CosimRun) -> dict[str, Any]:
    if isinstance(run, CosimRun):
        return cosim_report(run)
    r = run.result
    sc = run.scenario
    kinds = {name: int(np.sum(r.events.kind == i)) for i, name in enumerate(KIND_NAMES)}
    params = dict(sc.parameters)
    params["sim.engine"] = r.engine
    return {
        "scenario": sc.name,
        "description": sc.description,
        "source": sc.source,
        "engine": r.engine,
        "status": "ok" if r.ok else "failed",
        "message": r.message,
        "t_start": sc.sim["t_start"],
        "t_end": sc.sim["t_end"],
        "t_reached": r.t_reached,
        "wall_time_s": r.wall_time_s,
        "engine_load_s": r.warmup_s,
        "n_events": r.counters["events"],
        "n_impacts": r.counters["impacts"],
        "events_by_kind": kinds,
        "counters": r.counters,
        "forcing_period": sc.system.forcing_period,
        "poincare_points": int(run.strobe_rows.size),
        "parameters": params,
        "final_state": dict(zip(sc.system.state_names, map(float, r.final_state), strict=True)),
        "final_mode": r.final_mode,
        "outputs": sc.outputs,
    }
