"""Files the analysis commands write: data (npz, CSV), report.json and figures."""

from __future__ import annotations

import copy
import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from .cellmap import LABEL_BOUNDARY, LABEL_ESCAPE, Basins
from .motion import DEFAULT_TOL
from .published import compare, hsu_numbers
from .sweep import SweepResult


def checkpoint_dir(out: str | Path) -> Path:
    """Where an analysis writing to ``out`` keeps its checkpoint: beside it, so that
    ``out`` itself is only ever a complete result."""
    out = Path(out)
    return out.parent / f".{out.name}.checkpoint"


def _json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")


def write_sweep(
    result: SweepResult,
    tmp: Path,
    scenario_name: str,
    plot_state: int | str = 0,
    grazings: list[dict[str, Any]] | None = None,
    multipliers: dict[str, list[dict[str, Any] | None]] | None = None,
) -> None:
    """``sweep.npz``, ``sweep.csv`` (one row per stroboscopic point), ``report.json``
    (per value: n-m, distinct points, Floquet multipliers if asked; located grazings)
    and ``bifurcation.png`` (and ``grazing.png``, the square-root law, when grazings
    were located).  ``grazings`` and ``multipliers`` default to the result's own."""
    grazings = result.grazings if grazings is None else grazings
    multipliers = result.multipliers if multipliers is None else multipliers
    dirs = list(result.points)
    np.savez_compressed(
        tmp / "sweep.npz",
        values=result.values,
        state_names=np.array(result.state_names),
        **{f"points_{d}": result.points[d] for d in dirs},
        **{f"impacts_{d}": result.impacts[d] for d in dirs},
        **{f"modes_{d}": result.modes[d] for d in dirs},
        **{f"status_{d}": result.status[d] for d in dirs},
        **{f"impact_phase_{d}": result.impact_phase[d] for d in dirs},
    )
    rows = []
    for d_i, d in enumerate(dirs):
        n_v, n_k, n = result.points[d].shape
        vi, ki = np.meshgrid(np.arange(n_v), np.arange(n_k), indexing="ij")
        columns = [
            np.full(vi.size, d_i),
            result.values[vi.ravel()],
            ki.ravel(),
            result.points[d].reshape(-1, n),
            result.impacts[d].ravel(),
        ]
        if result.lyapunov:
            largest = np.array([np.nan if v is None else v for v in result.lyapunov[d]])
            columns.append(largest[vi.ravel()])
        rows.append(np.column_stack(columns))
    header = ["direction", result.param.name, "period_index", *result.state_names, "impacts"]
    if result.lyapunov:
        header.append("largest_lyapunov_per_s")
    np.savetxt(
        tmp / "sweep.csv",
        np.vstack(rows),
        delimiter=",",
        header=",".join(header),
        comments="",
        fmt="%.12g",
    )
    per_dir = {d: result.classify(d) for d in dirs}
    for d, rows in (multipliers or {}).items():
        for entry, f in zip(per_dir[d], rows, strict=True):
            entry["floquet"] = f
    for d, largest in result.lyapunov.items():
        for entry, lam in zip(per_dir[d], largest, strict=True):
            entry["largest_lyapunov_per_s"] = lam
    _json(
        tmp / "report.json",
        {
            "scenario": scenario_name,
            "parameter": result.param.name,
            "values": result.values.tolist(),
            "periods": result.periods,
            "discard": result.discard,
            "classification_tolerance_in_state_scales": DEFAULT_TOL,
            "directions": per_dir,
            "failed_values": {d: int(np.sum(result.status[d] != 0)) for d in dirs},
            "csv_direction_codes": {str(i): d for i, d in enumerate(dirs)},
            "grazing": grazings or [],
        },
    )
    _plot_sweep(result, tmp / "bifurcation.png", plot_state)
    if grazings:
        _plot_grazing(grazings, tmp / "grazing.png")


def _plot_grazing(grazings: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for g in grazings:
        law = g["sqrt_law"]
        d, dev = np.asarray(law["depths"]), np.asarray(law["deviations"])
        ax.loglog(
            d, dev, "o", label=f"{g['parameter']} = {g['value']:.8g}: slope {law['exponent']:.3f}"
        )
        ax.loglog(d, dev[0] * np.sqrt(d / d[0]), "k--", lw=0.8)
    ax.set_xlabel("penetration depth of the free orbit (length scales)")
    ax.set_ylabel("|impacting map - free map| (state scales)")
    ax.set_title("grazing: square-root law (dashed: slope 1/2)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def _plot_sweep(result: SweepResult, path: Path, state: int | str) -> None:
    """Stroboscopic coordinate ``state`` (an index) against the parameter, or with
    ``state = "impact"`` the impact section: the forcing phase of every impact."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dirs = list(result.points)
    fig, axes = plt.subplots(len(dirs), 1, figsize=(8, 3.6 * len(dirs)), squeeze=False)
    vmax = max(1, max(int(result.impacts[d].max()) for d in dirs))
    for ax, d in zip(axes[:, 0], dirs, strict=True):
        if state == "impact":
            pts = result.impact_phase[d]
            # coloured by the value's mean impacts per period
            colour = np.repeat(result.impacts[d].mean(axis=1), pts.shape[1])
            ylabel = "forcing phase of impacts (rad)"
        else:
            pts = result.points[d][:, :, state]
            colour = result.impacts[d].ravel()
            ylabel = f"{result.state_names[state]} at t = kT"
        x = np.repeat(result.values, pts.shape[1])
        sc = ax.scatter(
            x,
            pts.ravel(),
            c=colour,
            s=0.6,
            cmap="viridis",
            vmin=0,
            vmax=vmax,
            rasterized=True,
        )
        ax.set_ylabel(ylabel)
        ax.set_title(f"sweep {d}")
        fig.colorbar(sc, ax=ax, label="impacts per period")
    axes[-1, 0].set_xlabel(result.param.name)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def write_basins(
    basins: Basins, tmp: Path, scenario_name: str, info: dict[str, Any], figures: Any = None
) -> None:
    """``basins.npz``, ``report.json`` and ``basins.png``, the three at once: the npz is
    compressed on a thread (zlib releases the interpreter lock) and the figure drawn by
    ``figures`` (a :class:`rubcosim.figure_process.FigureProcess`: another process) when
    given, else here."""
    g = basins.grid
    arrays = {
        "labels": basins.labels,
        "attractor_of": basins.attractor_of,
        "reach": basins.reach,
        "image": basins.image.astype(np.int32),
        "centres": g.centres(),
        "grid": np.array([g.nx, g.nv]),
        "region": np.array([g.x0, g.x1, g.v0, g.v1]),
        "slice": np.array(info.get("slice") or info.get("state_names", ["x", "x'"])[:2]),
        "saddle_cells": np.concatenate(basins.saddles) if basins.saddles else np.zeros(0, int),
        **({} if basins.shares is None else {"shares": basins.shares, "fates": basins.fates}),
    }
    names = info.get("slice") or info.get("state_names", ["x", "x'"])
    with ThreadPoolExecutor(max_workers=1) as npz:
        written = npz.submit(np.savez_compressed, tmp / "basins.npz", **arrays)
        if figures is not None:
            # what the figure needs, without the per-sample arrays (megabytes to pickle)
            light = copy.copy(basins)
            light.image = light.fates = light.shares = None
            figures.submit(_plot_basins, light, tmp / "basins.png", names)
        _write_basins_report(basins, tmp, scenario_name, info)
        if figures is None:
            _plot_basins(basins, tmp / "basins.png", names)
        else:
            figures.wait()
        written.result()  # its error, if any, is raised here


def _write_basins_report(
    basins: Basins, tmp: Path, scenario_name: str, info: dict[str, Any]
) -> None:
    """``report.json``."""
    g = basins.grid
    counts = basins.counts()
    attractors = []
    for k in range(basins.n_attractors):
        cells = np.flatnonzero(basins.attractor_of == k)
        attractors.append(
            {
                "id": k,
                "cells": cells.tolist(),
                "hsu_cells": hsu_numbers(g, cells),
                "chain_period": basins.chain_periods[k],
                "basin_cells": counts["basins"][k],
                **basins.motions[k],
            }
        )
    _json(
        tmp / "report.json",
        {
            "scenario": scenario_name,
            "grid": [g.nx, g.nv],
            "region": {"x": [g.x0, g.x1], "v": [g.v0, g.v1]},
            "samples_per_cell": basins.samples,
            "seed": basins.seed,
            "cell_numbering": "c = j * nx + i (i: x index from x0, j: x' index from v0); "
            "c = nx * nv is the sink",
            "labels": f"basin k >= 0; {LABEL_BOUNDARY} boundary; {LABEL_ESCAPE} escape",
            "attractors": attractors,
            "counts": {
                "basins": counts["basins"],
                "boundary": counts["boundary"],
                "escape": counts["escape"],
            },
            "saddles": [
                {"cells": s.tolist(), "centres": g.centres(s).tolist()} for s in basins.saddles
            ],
            **_pursuit_report(basins, scenario_name),
            "metrics": _metrics(basins),
            **info,
        },
    )


def _metrics(basins: Basins) -> dict[str, Any]:
    """The basin metrics (:mod:`.basin_metrics`), or why they could not be computed."""
    import time

    from .errors import AnalysisError

    start = time.perf_counter()
    try:
        found = basins.metrics()
    except AnalysisError as exc:
        return {"error": str(exc)}
    return {**found, "seconds": time.perf_counter() - start}


def _pursuit_report(basins: Basins, scenario_name: str) -> dict[str, Any]:
    """What the pursuit method adds: the fixed points (Newton), the samples' shares and
    the comparison with a published structure of this scenario."""
    if basins.shares is None:
        return {}
    g = basins.grid
    total = g.n_cells * basins.samples
    sink = basins.shares[:, -1]
    out: dict[str, Any] = {
        "fixed_points": [
            {**p, "state": np.asarray(p["state"]).tolist(), "hsu_cell": p["cell"] + 1}
            for p in basins.fixed_points
        ],
        "samples": {
            "total": total,
            "per_attractor": [m["samples"] for m in basins.motions],
            "fraction_per_attractor": [m["sample_fraction"] for m in basins.motions],
            "sink_fraction": float(sink.sum() * basins.samples / total),
        },
        "cells_partly_to_the_sink": int(np.sum((sink > 0) & (sink < 1))),
    }
    cmp = compare(basins, scenario_name)
    if cmp is not None:
        out["published"] = cmp
    return out


def _plot_basins(basins: Basins, path: Path, names: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    g = basins.grid
    k = basins.n_attractors
    # 0: escape (white), 1: boundary (black), 2..: basins
    palette = ["#ffffff", "#000000", *plt.cm.Pastel1.colors[: max(k, 1)]][: k + 2]
    img = np.where(basins.labels >= 0, basins.labels + 2, 0)
    img[basins.labels == LABEL_BOUNDARY] = 1
    img = img.reshape(g.nv, g.nx)
    fig, ax = plt.subplots(figsize=(7, 6))
    ax.imshow(
        img,
        origin="lower",
        extent=(g.x0, g.x1, g.v0, g.v1),
        aspect="auto",
        cmap=ListedColormap(palette),
        vmin=0,
        vmax=k + 1,
        interpolation="nearest",
    )
    marks = "o^sDvP*"
    for a in range(k):
        c = g.centres(np.flatnonzero(basins.attractor_of == a))
        ax.plot(c[:, 0], c[:, 1], ".", ms=2, color=plt.cm.Set1(a % 9))
        m = basins.motions[a]  # on a slice: the points' projections onto it
        pts = np.asarray(m.get("slice_points", m.get("poincare_points", [])))
        if pts.size:
            ax.plot(
                pts[:, 0],
                pts[:, 1],
                marks[a % len(marks)],
                color=plt.cm.Set1(a % 9),
                mec="k",
                ms=8,
                label=f"attractor {a}: {basins.motions[a]['label']}",
            )
    axes = basins.info.get("slice_axes", [0, 1])
    sec = [np.asarray(m.get("section_points", [])) for m in basins.motions]
    sec = [p[:, axes] if p.size else p for p in sec]
    for a, pts in enumerate(sec):  # a non-periodic attractor: its section points
        if pts.size:
            ax.plot(pts[:, 0], pts[:, 1], ".", ms=1.5, color=plt.cm.Set1(a % 9))
    fps = [p for p in basins.fixed_points if p.get("saddle")]
    for s in basins.saddles:
        c = g.centres(s)
        ax.plot(c[:, 0], c[:, 1], "x", color="red", ms=4 if not fps else 9, mew=2)
    for p in fps:
        ax.annotate(f"saddle {p['cell'] + 1}", p["state"], fontsize=7, color="red")
    if basins.saddles:
        ax.plot([], [], "x", color="red", label="saddle cells")
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    title = "basins of attraction (black: boundary cells)"
    if basins.method == "slice":
        title += "\nslice: the other states at their initial values"
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
