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

_MARKERS = {"fold": "o", "branch-point": "P", "flip": "s", "neimark-sacker": "D",
            "grazing": "v"}  # fmt: skip


def branches_of(branch: Branch) -> list[Branch]:
    """The branch and those of its cascade, if any, in the order they were continued."""
    return list(branch.cascade.branches) if branch.cascade is not None else [branch]


def branch_table(branch: Branch) -> tuple[list[str], np.ndarray]:
    """The column names and rows of ``branch.csv`` (every branch of a cascade, its
    period in the first column)."""
    n = len(branch.state_names)
    names = ["period", branch.param, *branch.state_names, "impacts", "stable",
             "spectral_radius"]  # fmt: skip
    for i in range(n):
        names += [f"multiplier_{i + 1}_re", f"multiplier_{i + 1}_im"]
    names.append("residual")
    rows = []
    for b in branches_of(branch):
        for p in b.points:
            mult = [v for z in p.multipliers for v in (z.real, z.imag)]
            rows.append([b.period, p.param, *p.state, p.impacts, float(p.stable),
                         p.spectral_radius, *mult, p.residual])  # fmt: skip
    return names, np.array(rows, dtype=float).reshape(len(rows), len(names))


def _summary(b: Branch) -> dict[str, Any]:
    return {
        "period": b.period,
        "points": len(b.points),
        "stable_points": int(b.stable.sum()),
        "param_range_covered": [float(b.params.min()), float(b.params.max())] if b.points else [],
        "max_residual": max((p.residual for p in b.points), default=None),
        "impacts_per_period": sorted({p.impacts for p in b.points}),
        "stop_reason": b.stop_reason,
        "special_points": [{"period": b.period, **s.report()} for s in b.special],
    }


def branch_report(branch: Branch, settings: dict[str, Any]) -> dict[str, Any]:
    """``report.json``'s content: the first branch's summary at the top level, every
    branch's in ``branches``, the cascade's flips and ratios in ``cascade``."""
    every = [_summary(b) for b in branches_of(branch)]
    return {
        "scenario": branch.scenario,
        "analysis": "continuation",
        "param": branch.param,
        "settings": settings,
        **every[0],
        "branches": every,
        "cascade": None if branch.cascade is None else branch.cascade.report(),
    }


def write_continuation(
    branch: Branch,
    tmp: Path,
    settings: dict[str, Any],
    plot_state: int = 0,
    over_sweep: Path | None = None,
    curve: Any = None,
) -> None:
    """Write ``branch.csv``, ``report.json`` and ``branch.png`` into ``tmp`` (and
    ``curve.csv``, ``curve.png`` for a two-parameter ``curve``)."""
    names, rows = branch_table(branch)
    np.savetxt(tmp / "branch.csv", rows, delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")  # fmt: skip
    report = branch_report(branch, settings)
    if curve is not None:
        report["curve"] = write_curve(curve, tmp)
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
    for c, b in enumerate(branches_of(branch)):
        _draw_branch(top, b, state, f"C{c}")
        bottom.plot(b.params, [p.spectral_radius for p in b.points], ".", ms=2.5,
                    color=f"C{c}", label=f"period {b.period}")  # fmt: skip
    for kind, marker in _MARKERS.items():
        pts = [p for b in branches_of(branch) for p in b.special_of(kind)]
        if pts:
            top.plot([p.param for p in pts], [p.state[state] for p in pts], marker, ms=7,
                     mfc="none", mec="k", label=kind)  # fmt: skip
    top.set_ylabel(f"{branch.state_names[state]} at t = kT")
    top.set_title(f"{branch.scenario}: periodic orbits continued in {branch.param}")
    top.legend(fontsize=8)
    bottom.axhline(1.0, color="k", lw=0.8)
    bottom.set_yscale("log")
    bottom.set_ylabel("largest |multiplier|")
    bottom.set_xlabel(branch.param)
    bottom.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _draw_branch(ax: Any, b: Branch, state: int, colour: str) -> None:
    """Every section point of every orbit of ``b``: stable solid, unstable dashed."""
    mu, stable = b.params, b.stable
    pts = b.section_points or [p.state[None, :] for p in b.points]
    ys = np.array([q[:, state] for q in pts])  # (points, n)
    labelled: set[bool] = set()
    edges = [0, *(np.flatnonzero(stable[1:] != stable[:-1]) + 1), len(mu)]
    for a, z in zip(edges[:-1], edges[1:], strict=True):  # runs of one stability
        s = bool(stable[a])
        run = slice(a, min(z + 1, len(mu)))  # joined to the next run's first point
        lines = ax.plot(mu[run], ys[run], "-" if s else "--", color=colour, lw=1.2)
        if s not in labelled:
            lines[0].set_label(f"period {b.period}, {'stable' if s else 'unstable'}")
            labelled.add(s)


def write_curve(curve: Any, tmp: Path) -> dict[str, Any]:
    """``curve.csv`` (mu1, mu2, the state, the multipliers, the residual) and
    ``curve.png`` (mu2 against mu1) of a two-parameter curve; returns its summary."""
    names, rows = branch_table(curve)
    names.insert(2, curve.param2)
    rows = np.insert(rows, 2, curve.params2, axis=1)
    np.savetxt(tmp / "curve.csv", rows, delimiter=",", header=",".join(names), comments="",
               fmt="%.17g")  # fmt: skip
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    ax.plot(curve.params, curve.params2, "-", color="C3", lw=1.4, label=f"{curve.kind} curve")
    ax.plot(curve.params[:1], curve.params2[:1], "o", mfc="none", mec="k", label="start")
    ax.set_xlabel(curve.param)
    ax.set_ylabel(curve.param2)
    ax.set_title(f"{curve.scenario}: {curve.kind}s of the {curve.period}-periodic orbit")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(tmp / "curve.png", dpi=130)
    plt.close(fig)
    return {
        "kind": curve.kind,
        "param2": curve.param2,
        "points": len(curve.points),
        "stop_reason": curve.stop_reason,
        "max_residual": max((p.residual for p in curve.points), default=None),
        "param2_range_covered": [float(curve.params2.min()), float(curve.params2.max())],
    }


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
