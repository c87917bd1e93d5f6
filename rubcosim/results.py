"""Results of the Python API: a run's outputs by name, its events and counters, and a
co-simulation's comparison with the reference."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .runner import CosimRun, ScenarioRun, report
from .scenario import Scenario


@dataclass(frozen=True)
class EventLog:
    """Every event of a run in order: its time (s) and kind (``"impact"``, ...)."""

    t: np.ndarray
    kind: list[str]

    def times(self, kind: str) -> np.ndarray:
        """Times (s) of the events of one kind, e.g. ``"impact"``."""
        return self.t[[k == kind for k in self.kind]]

    def __len__(self) -> int:
        return self.t.size


class SimulationResult:
    """A scenario run (a monolithic engine or a co-simulation) on its output grid.

    ``res["rotor.x"]`` is an output over ``res.t`` (s; the grid up to the time reached,
    the rows of ``results.csv``), in the output's SI unit; ``res.names`` the recorded
    outputs.  ``status`` is ``"ok"`` or ``"failed"`` (then ``message`` says why).
    """

    def __init__(self, run: ScenarioRun | CosimRun) -> None:
        self.run = run
        self._keep = run.time <= run.result.t_reached + 1e-12

    @property
    def scenario(self) -> Scenario:
        return self.run.scenario

    @property
    def engine(self) -> str:
        """``"fast"``, ``"accurate"``, ``"cosim-direct"`` or ``"cosim-fmu"``."""
        return self.run.result.engine

    @property
    def names(self) -> list[str]:
        """The recorded outputs, ``unit.variable``."""
        return list(self.scenario.outputs)

    @property
    def t(self) -> np.ndarray:
        """Output times, s."""
        return self.run.time[self._keep]

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self.names:
            raise KeyError(f"{name!r} is not a recorded output (recorded: {', '.join(self.names)})")
        return self.run.series(name)[self._keep]

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __iter__(self) -> Iterator[str]:
        return iter(self.names)

    def poincare(self, name: str) -> np.ndarray:
        """An output at the stroboscopic section (``sim.poincare_phase``, after
        ``sim.poincare_discard``)."""
        return self.run.poincare(name)

    @property
    def ok(self) -> bool:
        return bool(self.run.result.ok)

    @property
    def status(self) -> str:
        return "ok" if self.ok else "failed"

    @property
    def message(self) -> str:
        return str(self.run.result.message)

    @property
    def counters(self) -> dict[str, int]:
        """Engine or master counters: ``events``, ``impacts`` (engines),
        ``events_impact``, ``steps``, ``rejected``... (co-simulation)."""
        return dict(self.run.result.counters)

    @property
    def t_reached(self) -> float:
        """Where the run ended, s (``t_end`` unless it failed)."""
        return float(self.run.result.t_reached)

    @property
    def wall_time_s(self) -> float:
        return float(self.run.result.wall_time_s)

    @property
    def events(self) -> EventLog:
        r = self.run.result
        if isinstance(self.run, CosimRun):
            return EventLog(np.asarray(r.event_t, dtype=float), list(r.event_kind))
        from rubcosim.reference.system import KIND_NAMES

        return EventLog(r.events.t, [KIND_NAMES[int(k)] for k in r.events.kind])

    def report(self) -> dict[str, Any]:
        """What ``report.json`` holds."""
        return report(self.run)

    def to_csv(self, path: str | Path) -> Path:
        """Write the same ``results.csv`` as ``rubcosim run``: time, then every output."""
        from .writing import write_csv

        return write_csv(self.run, path)

    def write(self, out_dir: str | Path, plots: bool = True) -> Path:
        """Write ``results.csv``, ``report.json`` and (``plots``) the plots, as ``rubcosim
        run`` does."""
        from .writing import write_results

        return write_results(self.run, out_dir, plots)

    def __repr__(self) -> str:
        return (
            f"<SimulationResult {self.scenario.name} {self.engine}: {self.status}, "
            f"t = {self.t_reached:g} s, {len(self.names)} outputs>"
        )


@dataclass
class CheckResult:
    """A co-simulation compared with the monolithic ``accurate`` engine (``rubcosim
    check``): ``report`` is ``report.json``."""

    scenario: Scenario
    report: dict[str, Any]
    reference: Any  # rubcosim.runner.ScenarioRun
    cosim: Any  # rubcosim.orchestrator.master.CosimResult
    rows: np.ndarray

    @property
    def ok(self) -> bool:
        """Whether the co-simulation ran to the end."""
        return bool(self.cosim.ok)

    @property
    def worst_rel_error(self) -> float:
        """The largest difference of an output, relative to the reference's largest value."""
        return float(self.report["worst_rel_error"])

    @property
    def chaos(self) -> dict[str, Any]:
        """How much of the difference a correct integration at the co-simulation's tolerance
        shows too, and whether chaos is why (:mod:`rubcosim.chaos_check`): ``verdict``
        (``regular``, or ``sensitive``/``chaotic`` then ``within the peer``/``beyond the
        peer``), the peer's difference, the largest Lyapunov exponent (1/s), the horizon (s),
        and past the horizon (``beyond_horizon``) the impact rates (1/s) and the distances of
        the outputs' distributions (Kolmogorov-Smirnov) of the peer and of the
        co-simulation, and whether they ``agree``."""
        return self.report["chaos"]

    def write(self, out_dir: str | Path, plots: bool = True) -> Path:
        """Write ``report.json`` and (``plots``) ``comparison.png`` (as ``rubcosim check``)."""
        from .writing import write_directory

        def fill(tmp: Path) -> None:
            text = json.dumps(self.report, indent=2) + "\n"
            (tmp / "report.json").write_text(text, encoding="utf-8")
            if not plots:
                return
            from rubcosim.consistency import comparison_plot  # matplotlib only when plotting

            comparison_plot(
                self.scenario, self.reference, self.cosim, self.rows, tmp / "comparison.png"
            )

        return write_directory(out_dir, fill)
