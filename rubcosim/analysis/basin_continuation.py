"""Basin fractions continued over a parameter, with the attractors matched from one value
to the next (as Attractors.jl's global continuation does).

At every value the basins are computed as ``rubcosim basins`` computes them (the same
grid, samples and seed, every fate checked on a sample by direct simulation).  The
attractors of one value are matched with those of the value before by the distance
between their points on the section (the smallest distance between the two point sets,
in state scales, plus ``match_distance`` when the two are motions of different kinds),
one to one (scipy's linear sum assignment), within ``match_distance``;
an attractor left over is matched by the overlap of the basins instead (the share of
its basin's cells that were in the other's basin), when that overlap is at least a
half.  An attractor without a match is born at that value; one of the value before
without a match died there, or merged into the attractor its basin went to.

Each value's result is kept in the checkpoint directory (when given) as it is done, so
an interrupted continuation resumes where it stopped.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import AnalysisError

MATCH_DISTANCE = 0.5  # state scales: farther, two attractors are not the same one
MIN_OVERLAP = 0.5


@dataclass
class Step:
    """One value's attractors: labels, points on the section, sample fractions (escape
    last), the cells' labels, the fate check, and the global ids given by matching."""

    value: float
    labels: list[str]
    points: list[np.ndarray]
    fractions: np.ndarray
    cell_labels: np.ndarray
    fate_check: dict[str, Any] | None
    ids: list[int] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "labels": self.labels,
            "points": [p.tolist() for p in self.points],
            "fractions": self.fractions.tolist(),
            "cell_labels": self.cell_labels.tolist(),
            "fate_check": self.fate_check,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Step:
        points = [np.asarray(p) for p in d["points"]]
        return cls(d["value"], d["labels"], points, np.asarray(d["fractions"]),
                   np.asarray(d["cell_labels"]), d["fate_check"])  # fmt: skip


def step_of(value: float, basins: Any) -> Step:
    """A value's :class:`Step` from its basins result."""
    n = basins.n_attractors
    labels = [m.get("label", "") for m in basins.motions]
    points = [np.atleast_2d(np.asarray(m.get("poincare_points", []), dtype=float))
              for m in basins.motions]  # fmt: skip
    if basins.fates is not None:
        f = np.bincount(np.asarray(basins.fates).ravel(), minlength=n + 1)[: n + 1]
    else:  # cell mapping: the cells' labels (escape last; boundary cells left out)
        lab = np.asarray(basins.labels)
        f = np.array([np.sum(lab == k) for k in range(n)] + [np.sum(lab == -1)])
    fractions = f / max(f.sum(), 1)
    return Step(float(value), labels, points, fractions, np.asarray(basins.labels),
                basins.info.get("fate_check"))  # fmt: skip


def set_distance(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> float:
    """The smallest distance between two point sets (rows), in state scales (max norm)."""
    if a.size == 0 or b.size == 0:
        return np.inf
    d = np.abs(a[:, None, :] - b[None, :, :]) / scale
    return float(d.max(axis=2).min())


def match(
    prev: Step, cur: Step, scale: np.ndarray, next_id: int, match_distance: float = MATCH_DISTANCE
) -> tuple[list[int], list[dict[str, Any]]]:
    """Global ids for ``cur``'s attractors (new ids from ``next_id``) and the events (born,
    died, merged) between the two values."""
    from scipy.optimize import linear_sum_assignment

    n_p, n_c = len(prev.points), len(cur.points)
    cost = np.full((n_p, n_c), np.inf)
    for i in range(n_p):
        for j in range(n_c):
            # another kind of motion (period, impacts, chaos) costs the whole threshold:
            # it is matched only where no motion of the same kind is as near
            other = 0.0 if prev.labels[i] == cur.labels[j] else match_distance
            cost[i, j] = set_distance(prev.points[i], cur.points[j], scale) + other
    ids = [-1] * n_c
    used: set[int] = set()
    if n_p and n_c:
        finite = np.where(np.isfinite(cost), cost, 1e300)
        for i, j in zip(*linear_sum_assignment(finite), strict=True):
            if cost[i, j] <= match_distance:
                ids[j] = prev.ids[i]
                used.add(i)
    overlap = _overlaps(prev, cur)
    for j in range(n_c):
        if ids[j] < 0:
            free = [i for i in range(n_p) if i not in used]
            best = max(free, key=lambda i: overlap[i, j], default=None)
            if best is not None and overlap[best, j] >= MIN_OVERLAP:
                ids[j] = prev.ids[best]
                used.add(best)
    events = []
    for j in range(n_c):
        if ids[j] < 0:
            ids[j] = next_id
            next_id += 1
            events.append({"event": "born", "attractor": ids[j], "value": cur.value,
                           "label": cur.labels[j]})  # fmt: skip
    for i in range(n_p):
        if i not in used:
            into = int(np.argmax(overlap[i])) if n_c else -1
            if n_c and overlap[i, into] >= MIN_OVERLAP:
                events.append({"event": "merged", "attractor": prev.ids[i], "value": cur.value,
                               "into": ids[into]})  # fmt: skip
            else:
                events.append({"event": "died", "attractor": prev.ids[i], "value": cur.value})
    return ids, events


def _overlaps(prev: Step, cur: Step) -> np.ndarray:
    """``[i, j]``: the share of ``prev``'s basin i cells that are in ``cur``'s basin j."""
    out = np.zeros((len(prev.points), len(cur.points)))
    if prev.cell_labels.shape != cur.cell_labels.shape:
        return out
    for i in range(out.shape[0]):
        cells = prev.cell_labels == i
        if cells.any():
            for j in range(out.shape[1]):
                out[i, j] = float(np.mean(cur.cell_labels[cells] == j))
    return out


@dataclass
class BasinContinuation:
    """Basin fractions over ``values`` of ``param``, attractors matched across values."""

    param: str
    values: np.ndarray
    steps: list[Step]
    events: list[dict[str, Any]]
    n_ids: int

    @property
    def fractions(self) -> np.ndarray:
        """``(values, attractors + 1)``: each global attractor's sample fraction, escape last."""
        out = np.zeros((len(self.steps), self.n_ids + 1))
        for r, s in enumerate(self.steps):
            for j, g in enumerate(s.ids):
                out[r, g] += s.fractions[j]
            out[r, -1] = s.fractions[-1]
        return out

    def attractor_labels(self) -> list[str]:
        """A label per global attractor: its motions' labels where it lives."""
        names: list[list[str]] = [[] for _ in range(self.n_ids)]
        for s in self.steps:
            for j, g in enumerate(s.ids):
                if s.labels[j] not in names[g]:
                    names[g].append(s.labels[j])
        return [f"A{g}: " + " / ".join(n) for g, n in enumerate(names)]

    def report(self) -> dict[str, Any]:
        checks = [s.fate_check for s in self.steps if s.fate_check]
        return {
            "param": self.param,
            "values": self.values.tolist(),
            "attractors": self.attractor_labels(),
            "fractions": self.fractions.tolist(),
            "events": self.events,
            "fates_checked": int(sum(c["checked"] for c in checks)),
            "fates_agreeing": int(sum(c["agree"] for c in checks)),
            "per_value": [
                {"value": s.value, "ids": s.ids, "labels": s.labels, "fate_check": s.fate_check}
                for s in self.steps
            ],  # fmt: skip
        }


def continue_basins(
    run: Callable[[float], Any],
    param: str,
    values: np.ndarray,
    scale: np.ndarray,
    checkpoint: Path | None = None,
    progress: Callable[[int], None] | None = None,
) -> BasinContinuation:
    """``run(value)`` (a basins result) at every value in order, matched as the module's
    docstring says; each value's result kept under ``checkpoint`` (resumed from it)."""
    values = np.asarray(values, dtype=float)
    if values.size < 2 or not np.all(np.isfinite(values)):
        raise AnalysisError(f"--continue {param}: at least two finite values")
    steps: list[Step] = []
    events: list[dict[str, Any]] = []
    next_id = 0
    for k, v in enumerate(values):
        saved = None if checkpoint is None else checkpoint / f"value_{k:04d}.json"
        if saved is not None and saved.is_file():
            step = Step.from_json(json.loads(saved.read_text()))
        else:
            step = step_of(v, run(float(v)))
            if saved is not None:
                saved.parent.mkdir(parents=True, exist_ok=True)
                saved.write_text(json.dumps(step.to_json()))
        if not steps:
            step.ids = list(range(len(step.points)))
            next_id = len(step.ids)
            events += [{"event": "present", "attractor": g, "value": step.value,
                        "label": step.labels[g]} for g in step.ids]  # fmt: skip
        else:
            step.ids, new = match(steps[-1], step, scale, next_id)
            next_id = max([next_id, *(g + 1 for g in step.ids)])
            events += new
        steps.append(step)
        if progress is not None:
            progress(k + 1)
    return BasinContinuation(param, values, steps, events, next_id)


def plot_fractions(result: BasinContinuation, path: Path) -> None:
    """The basin fractions stacked against the parameter (Attractors.jl's figure), with
    the births, deaths and merges marked on the axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = result.fractions
    names = [*result.attractor_labels(), "escape"]
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.stackplot(result.values, f.T, labels=names, alpha=0.85)
    for e in result.events:
        if e["event"] != "present":
            ax.axvline(e["value"], color="k", lw=0.6, ls=":")
    ax.set_xlim(result.values.min(), result.values.max())
    ax.set_ylim(0.0, 1.0)
    ax.set_xlabel(result.param)
    ax.set_ylabel("fraction of the samples")
    ax.set_title("basin fractions (dotted: an attractor born, died or merged)")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def write_basin_continuation(result: BasinContinuation, tmp: Path, scenario: str) -> None:
    """``fractions.csv`` (value, each attractor's fraction, escape), ``report.json`` and
    ``basin_fractions.png``."""
    names = [result.param, *result.attractor_labels(), "escape"]
    rows = np.column_stack((result.values, result.fractions))
    np.savetxt(tmp / "fractions.csv", rows, delimiter=",", comments="",
               header=",".join(n.replace(",", ";") for n in names), fmt="%.10g")  # fmt: skip
    (tmp / "report.json").write_text(
        json.dumps({"scenario": scenario, "analysis": "basin continuation", **result.report()},
                   indent=2) + "\n", encoding="utf-8"
    )  # fmt: skip
    plot_fractions(result, tmp / "basin_fractions.png")
