"""Published global structures to compare a basins result with, side by side.

Feng & Yang's case (``scenarios/feng_yang_attractors.toml``): their Figure 1
and Table 1, in Hsu's cell numbers ``z = (j - 1) nx + i`` (``i`` = 1 .. nx the
x index, x fastest; ``j`` the x' index; 1-based; the sink is ``nx nv + 1``)
on 200 x 200 cells over [-2, 1] x [-2, 2], 16 random points per cell.  The
published cells are converted to (x, x') here, from the paper's grid alone,
and each is matched with the nearest attractor or saddle found, wherever it
is (a result on another grid compares too).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .cellmap import Basins, Grid

PUBLISHED: dict[str, dict[str, Any]] = {
    "feng_yang_attractors": {
        "source": "Feng & Yang, Figure 1 and Table 1 (seeds/feng_yang_coexisting_attractors.txt)",
        "grid": (200, 200, -2.0, 1.0, -2.0, 2.0),
        "samples": 16,
        "attractors": {
            "P1": ([13950, 14147, 14148, 14149, 14150, 14347], "chaotic"),
            "P2": ([15579], "periodic"),
            "P3": ([25185], "periodic"),
            "P4": ([23398], "periodic"),
        },
        "saddles": {"S1": [13164], "S2": [20188]},
        "basin_cells": {"P1": 10097, "P2": 15574, "P3": 2255, "P4": 4706},
        "boundary_cells": 5351,
    }
}


def hsu_centre(z: int | np.ndarray, grid: tuple[int, int, float, float, float, float]) -> Any:
    """(x, x') centre of Hsu cell number(s) ``z`` (1-based, x fastest) on
    ``grid = (nx, nv, x0, x1, v0, v1)``."""
    nx, nv, x0, x1, v0, v1 = grid
    j, i = np.divmod(np.asarray(z) - 1, nx)
    return np.column_stack((x0 + (i + 0.5) * (x1 - x0) / nx, v0 + (j + 0.5) * (v1 - v0) / nv))


def hsu_numbers(grid: Grid, cells: np.ndarray) -> list[int]:
    """Hsu's 1-based numbers of 0-based cells ``c = j nx + i`` (the sink ``nx nv + 1``)."""
    return [int(c) + 1 for c in np.asarray(cells).ravel()]


def _distance(points: np.ndarray, target: np.ndarray, width: np.ndarray) -> float:
    """Smallest distance from ``target`` (x, x') to ``points``, in the paper's cell widths."""
    return float(np.min(np.max(np.abs(np.atleast_2d(points) - target) / width, axis=1)))


def compare(basins: Basins, scenario_name: str) -> dict[str, Any] | None:
    """Side by side with the published structure (``None`` when none is known)."""
    paper = PUBLISHED.get(scenario_name)
    if paper is None:
        return None
    pg = paper["grid"]
    width = np.array([(pg[3] - pg[2]) / pg[0], (pg[5] - pg[4]) / pg[1]])
    counts = basins.counts()
    total = basins.grid.n_cells * basins.samples
    rows = []
    for name, (cells, kind) in paper["attractors"].items():
        centre = hsu_centre(cells, pg).mean(axis=0)
        dist = []
        for m in basins.motions:
            pts = np.asarray(m.get("section_points") or m.get("poincare_points") or [[np.inf] * 2])
            dist.append(_distance(pts, centre, width))
        k = int(np.argmin(dist)) if dist else -1
        row = {
            "paper": name,
            "paper_kind": kind,
            "paper_cells": cells,
            "paper_centre": centre.tolist(),
            "paper_basin_cells": paper["basin_cells"][name],
        }
        if k >= 0:
            m = basins.motions[k]
            row |= {
                "attractor": k,
                "label": m["label"],
                "lyapunov": m.get("lyapunov"),
                "cells": hsu_numbers(basins.grid, np.flatnonzero(basins.attractor_of == k)),
                "distance_cells": dist[k],
                "basin_cells": counts["basins"][k],
                "sample_fraction": m.get("sample_fraction"),
            }
        rows.append(row)
    saddles = []
    found = [p for p in basins.fixed_points if p.get("saddle")]
    for name, cells in paper["saddles"].items():
        centre = hsu_centre(cells, pg)[0]
        row = {"paper": name, "paper_cells": cells, "paper_centre": centre.tolist()}
        if found:
            d = [_distance(np.asarray(p["state"]), centre, width) for p in found]
            p = found[int(np.argmin(d))]
            row |= {
                "cell": hsu_numbers(basins.grid, [p["cell"]])[0],
                "state": np.asarray(p["state"]).tolist(),
                "multipliers": p["multipliers"],
                "impacts": p["impacts"],
                "distance_cells": min(d),
            }
        saddles.append(row)
    same_grid = (
        basins.grid.nx,
        basins.grid.nv,
        basins.grid.x0,
        basins.grid.x1,
        basins.grid.v0,
        basins.grid.v1,
    ) == pg and basins.samples == paper["samples"]
    return {
        "source": paper["source"],
        "same_grid_as_paper": same_grid,
        "samples_total": total,
        "attractors": rows,
        "saddles": saddles,
        "boundary_cells": {"paper": paper["boundary_cells"], "found": counts["boundary"]},
        "escape_cells": counts["escape"],
    }


def found_label(row: dict[str, Any]) -> str:
    """An attractor row's label (n-m, or not periodic) with the largest Lyapunov
    exponent measured for a motion that is not periodic (1/s, over the attractor)."""
    label, lyap = str(row.get("label")), row.get("lyapunov")
    if isinstance(lyap, float) and np.isfinite(lyap):
        return f"{label}, largest Lyapunov exponent {lyap:+.4f} 1/s"
    return label


def basins_summary(basins: Basins, scenario_name: str) -> list[str]:
    """Lines printed after a basins run: the fixed points found, and the comparison
    with the published structure when there is one."""
    lines = []
    for p in basins.fixed_points:
        mult = ", ".join(f"{complex(*z):.4g}" for z in p["multipliers"])
        kind = "saddle" if p["saddle"] else ("stable" if p["stable"] else "unstable")
        lines.append(
            f"  fixed point ({p['state'][0]:.5f}, {p['state'][1]:.5f}) cell "
            f"{p['cell'] + 1} (Hsu): {kind}, {p['impacts']} impact(s), multipliers {mult}"
        )
    cmp = compare(basins, scenario_name)
    if cmp is None:
        return lines
    lines.append(f"  vs {cmp['source']} (same grid: {cmp['same_grid_as_paper']}):")
    for r in cmp["attractors"]:
        frac = r.get("sample_fraction")
        lines.append(
            f"  {r['paper']} {r['paper_kind']} cells {r['paper_cells']} basin "
            f"{r['paper_basin_cells']} | found {found_label(r)} cells {r.get('cells')} "
            f"({r.get('distance_cells', np.nan):.1f} paper cells away) basin "
            f"{r.get('basin_cells')}, {100 * frac if frac is not None else np.nan:.2f} % of "
            f"the {cmp['samples_total']} samples"
        )
    for r in cmp["saddles"]:
        lines.append(
            f"  {r['paper']} cell {r['paper_cells']} | found cell {r.get('cell')} "
            f"({r.get('distance_cells', np.nan):.1f} paper cells away), multipliers "
            f"{r.get('multipliers')}"
        )
    b = cmp["boundary_cells"]
    lines.append(
        f"  boundary cells: paper {b['paper']}, found {b['found']}; escape {cmp['escape_cells']}"
    )
    return lines
