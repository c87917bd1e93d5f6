"""Consistency check: a co-simulation against the monolithic ``accurate`` reference.

Both run the same scenario and record the same outputs at the same times.
Per output the report gives the largest absolute difference over the output
grid and that difference relative to the largest magnitude the reference
reaches (``max_rel_error``); impact times are compared in order.  On a chaotic motion
the report also says how much of the difference chaos accounts for
(:mod:`.chaos_check`: the ``chaos`` block).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.orchestrator.master import CosimResult
from rubcosim.orchestrator.settings import CosimSettings

from .chaos_check import assess, impacts_after, output_errors, worst
from .timegrid import output_times


def impact_count(result: CosimResult) -> int:
    """Impacts of a co-simulation: the master's impact events, or an oscillator's own count
    (:func:`.chaos_check.impacts_after` the start)."""
    return impacts_after(result, -math.inf)


def nearest_differences(times: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """For every time, the distance to the nearest reference time (impacts are matched by
    time, not by index: a chattering sequence can end after fewer rebounds)."""
    if times.size == 0 or reference.size == 0:
        return np.zeros(0)
    last = reference.size - 1
    i = np.searchsorted(reference, times)
    left = reference[np.clip(i - 1, 0, last)]
    right = reference[np.clip(i, 0, last)]
    return np.minimum(np.abs(times - left), np.abs(times - right))


def compare(
    scenario: Any,
    settings: CosimSettings | None = None,
    fmu_dir: Path | None = None,
    progress: bool = False,
):
    """Run both and return ``(report, reference_run, cosim_result, grid_rows)``;
    ``progress``: bars in simulated time on a terminal for long runs."""
    from .runner import run_scenario

    settings = settings or scenario.cosim
    ref = run_scenario(scenario, engine="accurate", progress=progress)
    times, grid_rows, _ = output_times(scenario)
    record = list(scenario.outputs)
    if "oscillator" in scenario.graph.units:
        record.append("oscillator.impacts")
    co = run_cosim(
        scenario, settings, record=record, times=times, fmu_dir=fmu_dir, progress=progress
    )
    n = min(len(co.t), ref.result.t.size)
    rows = grid_rows[grid_rows < n]
    outputs = output_errors(ref.result, co, list(scenario.outputs), rows)
    ref_impacts = ref.result.events.t[ref.result.events.of_kind("impact")]
    co_impacts = co.events_of_kind("impact")
    diffs = nearest_differences(co_impacts, ref_impacts)
    k = diffs.size
    report = {
        "scenario": scenario.name,
        "source": scenario.source,
        "status": co.status,
        "message": co.message,
        "reference_status": "ok" if ref.result.ok else "failed",
        "t_end": scenario.sim["t_end"],
        "t_reached": co.t_reached,
        "settings": {
            k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(co.settings).items()
        },
        "input_orders": co.input_orders,
        "master": co.master,
        "outputs": outputs,
        "worst_rel_error": worst(outputs),
        "impacts": {"reference": int(ref_impacts.size), "cosim": impact_count(co)},
        "impact_time_max_diff_s": float(diffs.max()) if k else None,  # to the nearest one
        "impacts_compared": int(k),
        "wall_time_s": {"reference": ref.result.wall_time_s, "cosim": co.wall_time_s},
        "counters": co.counters,
    }
    report["chaos"] = assess(scenario, ref, co, rows, settings.rtol)
    return report, ref, co, rows


def comparison_plot(scenario: Any, ref: Any, co: CosimResult, rows: np.ndarray, path: Path) -> None:
    """Reference and co-simulation of the first two outputs, and their differences."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = scenario.outputs[:2]
    fig, axes = plt.subplots(len(names), 2, figsize=(11, 3.2 * len(names)), squeeze=False)
    t = co.t[rows]
    for i, name in enumerate(names):
        a = ref.result.output(name)[rows]
        b = co.output(name)[rows]
        axes[i, 0].plot(t, a, lw=1.6, label="reference (accurate)")
        axes[i, 0].plot(t, b, "--", lw=0.9, label=f"co-simulation ({co.settings.backend})")
        axes[i, 0].set_ylabel(name)
        # differences below round-off of the signal are drawn at that level
        floor = 1e-16 * max(float(np.max(np.abs(a))) if a.size else 0.0, 1e-300)
        axes[i, 1].semilogy(t, np.maximum(np.abs(a - b), floor), lw=0.7)
        axes[i, 1].set_ylabel(f"|difference| of {name}")
    axes[0, 0].legend(fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    axes[-1, 1].set_xlabel("t [s]")
    fig.suptitle(f"{scenario.name}: co-simulation vs monolithic reference")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
