"""Scenario plots: orbit, time series, stroboscopic Poincare section (PNG)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

# The object-oriented API on the Agg canvas: no pyplot (its import and figure manager
# cost more than the three plots of a small run), no mathtext in the tick offsets, and
# fixed margins instead of a layout engine (each measured at a few tenths of a second).
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import ScalarFormatter

DPI = 120

if TYPE_CHECKING:
    from .runner import ScenarioRun


def _sci(ax) -> None:
    """Scientific tick labels with a shared exponent (displacements are ~1e-4 m) on the
    numeric axes (an axis of texts, a String output of a foreign FMU, has categories)."""
    for axis in ("x", "y"):
        if isinstance(getattr(ax, f"{axis}axis").get_major_formatter(), ScalarFormatter):
            ax.ticklabel_format(axis=axis, style="sci", scilimits=(-2, 3), useMathText=False)


def _default_pair(run: ScenarioRun) -> list[str]:
    names = run.scenario.system.output_names
    return ["rotor.x", "rotor.y"] if "rotor.y" in names else ["oscillator.x", "oscillator.v"]


def _stator_circle(run: ScenarioRun, ax) -> bool:
    """Draw the stator's clearance circle; False when the scenario has no stator."""
    units = run.scenario.system.units
    if "stator" not in units:
        return False
    s = units["stator"].params
    th = np.linspace(0.0, 2.0 * np.pi, 361)
    ax.plot(
        s["x_offset"] + s["clearance"] * np.cos(th),
        s["y_offset"] + s["clearance"] * np.sin(th),
        "k--",
        lw=0.8,
        label="stator (clearance)",
    )
    return True


def _figure(width: float, height: float, margins: tuple[float, float, float, float]) -> Figure:
    """A figure on the Agg canvas with fixed ``(left, bottom, right, top)`` margins."""
    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    left, bottom, right, top = margins
    fig.subplots_adjust(left=left, bottom=bottom, right=right, top=top)
    return fig


SQUARE = (0.16, 0.11, 0.95, 0.91)


def orbit(run: ScenarioRun, names: list[str], path: Path) -> None:
    fig = _figure(5.5, 5.0, SQUARE)
    ax = fig.subplots()
    ax.plot(run.series(names[0]), run.series(names[1]), lw=0.6)
    if names == ["rotor.x", "rotor.y"]:
        ax.set_aspect("equal")
        if _stator_circle(run, ax):
            ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    _sci(ax)
    ax.set_title(f"{run.scenario.name}: orbit ({run.result.engine})", fontsize=10)
    fig.savefig(path, dpi=DPI)


def timeseries(run: ScenarioRun, names: list[str], path: Path) -> None:
    height = 1.9 * len(names) + 0.6
    fig = _figure(8.0, height, (0.11, 0.5 / height, 0.97, 1.0 - 0.35 / height))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)
    fig.subplots_adjust(hspace=0.3)
    for ax, name in zip(axes[:, 0], names, strict=True):
        values = run.series(name)
        # a text (a foreign FMU's String output) holds from one output time to the next
        steps = "steps-post" if values.dtype.kind in "UO" else "default"
        ax.plot(run.time, values, lw=0.7, drawstyle=steps)
        ax.set_ylabel(name, fontsize=8)
        _sci(ax)
    axes[-1, 0].set_xlabel("time (s)")
    axes[0, 0].set_title(f"{run.scenario.name}: time series ({run.result.engine})", fontsize=10)
    fig.savefig(path, dpi=DPI)


def poincare(run: ScenarioRun, names: list[str], path: Path) -> None:
    fig = _figure(5.5, 5.0, SQUARE)
    ax = fig.subplots()
    ax.plot(run.poincare(names[0]), run.poincare(names[1]), ".", ms=3)
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    _sci(ax)
    sim = run.scenario.sim
    first = sim["t_start"] + sim["poincare_discard"]
    ax.set_title(
        f"{run.scenario.name}: stroboscopic section, "
        f"phase {sim['poincare_phase']:g} rad, t >= {first:g} s",
        fontsize=8,
    )
    fig.savefig(path, dpi=DPI)


def scenario_plots(run: ScenarioRun, out: Path) -> list[Path]:
    """Write orbit.png, timeseries.png and poincare.png into ``out``."""
    pl = run.scenario.plots
    pair = _default_pair(run)
    written = []
    for kind, func, default in (
        ("orbit", orbit, pair),
        ("timeseries", timeseries, pair),
        ("poincare", poincare, pair),
    ):
        path = out / f"{kind}.png"
        func(run, pl.get(kind, default), path)
        written.append(path)
    return written


def control_success_figure(study, path: Path) -> Path:
    """Success rate of a control study against the gain (one line per memory R) and
    against R (one line per gain), PNG."""
    rates = study.success_rates()
    gains = sorted({g for g, _ in rates})
    memories = sorted({m for _, m in rates})
    fig = _figure(10.0, 4.2, (0.08, 0.13, 0.98, 0.88))
    ax1, ax2 = fig.subplots(1, 2)
    for m in memories:
        ax1.plot(gains, [100 * rates[(g, m)] for g in gains], "o-", label=f"R = {m:g}")
    for g in gains:
        ax2.plot(memories, [100 * rates[(g, m)] for m in memories], "s-", label=f"K = {g:g}")
    ax1.set_xlabel("gain K")
    ax2.set_xlabel("ETDAS memory R")
    for ax in (ax1, ax2):
        ax.set_ylabel("runs converged (%)")
        ax.set_ylim(-5, 105)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    n = len(study.runs) // max(1, len(rates))
    fig.suptitle(f"{study.scenario}: delayed feedback, {n} switch-on times per point")
    fig.savefig(path, dpi=DPI)
    return path
