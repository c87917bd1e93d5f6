"""Files ``rubcosim continue`` writes: the branch table, report.json and the figure.

* ``branch.csv``: one row per point in arclength order: the parameter, the state on the
  section, the impacts per n periods, stability, the spectral radius, every multiplier
  (real and imaginary parts, largest modulus first) and Newton's residual;
* ``report.json``: the settings, why the continuation stopped, and the special points
  (fold, flip, Neimark-Sacker, branch point) with their state and multipliers;
* ``branch.png``: a state on the section against the parameter, stable solid, unstable
  dashed, special points marked; below it the multipliers' moduli, with the unit circle's
  radius.  With a sweep's ``sweep.npz`` (``--over-sweep``), the sweep's stroboscopic
  points of the same state are drawn beneath the branch.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .continuation import Branch
from .errors import AnalysisError

_MARKERS = {"fold": "o", "branch-point": "P", "flip": "s", "neimark-sacker": "D"}


def branch_table(branch: Branch) -> tuple[list[str], np.ndarray]:
    """The column names and rows of ``branch.csv``."""
    n = len(branch.state_names)
    names = [branch.param, *branch.state_names, "impacts", "stable", "spectral_radius"]
    for i in range(n):
        names += [f"multiplier_{i + 1}_re", f"multiplier_{i + 1}_im"]
    names.append("residual")
    rows = []
    for p in branch.points:
        mult = [v for z in p.multipliers for v in (z.real, z.imag)]
        rows.append(
            [p.param, *p.state, p.impacts, float(p.stable), p.spectral_radius, *mult, p.residual]
        )
    return names, np.array(rows, dtype=float).reshape(len(rows), len(names))


def branch_report(branch: Branch, settings: dict[str, Any]) -> dict[str, Any]:
    """``report.json``'s content."""
    stable = branch.stable
    return {
        "scenario": branch.scenario,
        "analysis": "continuation",
        "param": branch.param,
        "period": branch.period,
        "settings": settings,
        "points": len(branch.points),
        "stable_points": int(stable.sum()),
        "param_range_covered": [float(branch.params.min()), float(branch.params.max())]
        if branch.points
        else [],
        "max_residual": max((p.residual for p in branch.points), default=None),
        "impacts_per_period": sorted({p.impacts for p in branch.points}),
        "stop_reason": branch.stop_reason,
        "special_points": [s.report() for s in branch.special],
    }


def write_continuation(
    branch: Branch,
    tmp: Path,
    settings: dict[str, Any],
    plot_state: int = 0,
    over_sweep: Path | None = None,
) -> None:
    """Write ``branch.csv``, ``report.json`` and ``branch.png`` into ``tmp``."""
    names, rows = branch_table(branch)
    np.savetxt(tmp / "branch.csv", rows, delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")  # fmt: skip
    report = branch_report(branch, settings)
    (tmp / "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    plot_branch(branch, tmp / "branch.png", plot_state, over_sweep)


def plot_branch(branch: Branch, path: Path, state: int = 0, over_sweep: Path | None = None) -> None:
    """The figure described in the module's docstring."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(8, 6.4), sharex=True, gridspec_kw={"height_ratios": [2.2, 1]}
    )
    if over_sweep is not None:
        _draw_sweep(top, over_sweep, branch.state_names[state])
    mu, y, stable = branch.params, branch.states[:, state], branch.stable
    first = {True: True, False: True}
    for a in range(len(mu) - 1):  # each segment in the style of its first point
        s = bool(stable[a])
        top.plot(mu[a : a + 2], y[a : a + 2], "-" if s else "--", color="C0" if s else "C3",
                 lw=1.4, label=("stable" if s else "unstable") if first[s] else None)  # fmt: skip
        first[s] = False
    for kind, marker in _MARKERS.items():
        pts = branch.special_of(kind)
        if pts:
            top.plot([p.param for p in pts], [p.state[state] for p in pts], marker, ms=7,
                     mfc="none", mec="k", label=kind)  # fmt: skip
    top.set_ylabel(f"{branch.state_names[state]} at t = kT")
    top.set_title(f"{branch.scenario}: {branch.period}-periodic orbits continued in {branch.param}")
    top.legend(fontsize=8)
    moduli = np.abs(branch.multipliers)
    for i in range(moduli.shape[1]):
        bottom.plot(mu, moduli[:, i], ".", ms=2.5, label=f"|multiplier {i + 1}|")
    bottom.axhline(1.0, color="k", lw=0.8)
    bottom.set_yscale("log")
    bottom.set_ylabel("|Floquet multipliers|")
    bottom.set_xlabel(branch.param)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _draw_sweep(ax: Any, npz: Path, state_name: str) -> None:
    """A sweep's stroboscopic points of ``state_name`` (every direction), in grey."""
    with np.load(npz) as data:
        names = [str(n) for n in data["state_names"]]
        if state_name not in names:
            raise AnalysisError(f"--over-sweep {npz}: the sweep has no state {state_name!r}")
        k = names.index(state_name)
        values = data["values"]
        for key in [f for f in data.files if f.startswith("points_")]:
            pts = data[key][:, :, k]
            ax.plot(np.repeat(values, pts.shape[1]), pts.ravel(), ",", color="0.6",
                    rasterized=True)  # fmt: skip
