"""Lyapunov spectrum of Feng & Yang's chaotic attractor P1 (issue 13's target).

The motion starts at the centre of P1's first published cell (Hsu number 13950 on
the paper's grid: [-2, 1] x [-2, 2], 200 x 200 cells) on the stroboscopic section
of ``scenarios/feng_yang_attractors.toml``; ``--transient`` forcing periods are
discarded, then the spectrum is measured over ``--periods`` periods (the
variational equations on the fast engine, the saltation matrix at every impact,
Gram-Schmidt every period).  Also written: the exponents from the first half of the
periods (convergence), Liouville's sum (-b + 2 ln R x impacts per unit time), and
which published P1 cells the measured motion visits.  Run from the repository root::

    .venv/bin/python benchmarks/study_lyapunov.py [--periods 20000] [--transient 1000]

Writes ``lyapunov_feng_yang.json`` and ``.md`` to ``--out`` (default
``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numba
import numpy as np
from stamp import stamp

from rubcosim.analysis.lyapunov import lyapunov_report, lyapunov_spectrum
from rubcosim.analysis.maps import StroboscopicMap
from rubcosim.analysis.published import hsu_centre
from rubcosim.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
SCENARIO = REPO / "scenarios" / "feng_yang_attractors.toml"
GRID = (200, 200, -2.0, 1.0, -2.0, 2.0)
P1 = [13950, 14147, 14148, 14149, 14150, 14347]


def visited_cells(system, y0: np.ndarray, skip: int, keep: int) -> dict[int, int]:
    """Hsu cells of the stroboscopic points of the measured motion, with their counts."""
    pts = StroboscopicMap(system, 1e-10).orbit(y0, skip=skip, keep=keep).points
    nx, nv, x0, x1, v0, v1 = GRID
    i = np.floor((pts[:, 0] - x0) / (x1 - x0) * nx).astype(int)
    j = np.floor((pts[:, 1] - v0) / (v1 - v0) * nv).astype(int)
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < nv)
    z = j[inside] * nx + i[inside] + 1
    cells, counts = np.unique(z, return_counts=True)
    return {int(c): int(n) for c, n in zip(cells, counts, strict=True)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--periods", type=int, default=20000, help="forcing periods measured")
    ap.add_argument("--transient", type=int, default=1000, help="forcing periods discarded")
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    args = ap.parse_args(argv)
    system = load_scenario(SCENARIO).system
    y0 = hsu_centre(P1[0], GRID)[0]
    t0 = time.perf_counter()
    lyap = lyapunov_spectrum(system, args.periods, args.transient, y0=y0)
    wall = time.perf_counter() - t0
    cells = visited_cells(system, y0, args.transient, min(args.periods, 5000))
    b, R, T = 0.02, 0.8, lyap.interval
    report = {
        "meta": stamp(
            command="benchmarks/study_lyapunov.py "
            f"--periods {args.periods} --transient {args.transient}"
        ),
        "start": {"hsu_cell": P1[0], "x": float(y0[0]), "v": float(y0[1])},
        "spectrum": lyapunov_report(lyap),
        "liouville_closed_form": -b + 2.0 * math.log(R) * lyap.impacts / (lyap.intervals * T),
        "wall_s": wall,
        "published_P1_cells_visited": {str(z): cells.get(z, 0) for z in P1},
        "cells_visited": len(cells),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "lyapunov_feng_yang.json").write_text(json.dumps(report, indent=2) + "\n")
    s = report["spectrum"]
    lam = s["exponents_per_unit_time"]
    lines = [
        "# Lyapunov spectrum of Feng & Yang's chaotic attractor P1",
        "",
        f"`{report['meta']['command']}` ({report['meta']['date']}, commit "
        f"{report['meta']['git_commit'][:10]}, Python {report['meta']['python']}, numpy "
        f"{np.__version__}, numba {numba.__version__}; {wall:.1f} s).",
        "",
        f"Start: the centre of cell {P1[0]} (x = {y0[0]:.4f}, x' = {y0[1]:.4f}) at phase 0; "
        f"{args.transient} periods discarded, {args.periods} measured "
        f"(T = {T:.6f} s), {s['impacts_per_interval']:.4f} impacts per period.",
        "",
        "| exponent | per unit time (1/s) | per period | first half (1/s) |",
        "|---|---|---|---|",
    ]
    for k, (a, p, h) in enumerate(
        zip(lam, s["exponents_per_interval"], s["first_half_per_unit_time"], strict=True)
    ):
        lines.append(f"| {k + 1} | {a:+.5f} | {p:+.5f} | {h:+.5f} |")
    lines += [
        "",
        f"Sum {s['sum']:+.6f} 1/s; Liouville (tr J + ln|det S|) {s['liouville_sum']:+.6f}; "
        f"closed form -b + 2 ln R x impacts per unit time "
        f"{report['liouville_closed_form']:+.6f}.",
        "",
        "Published P1 cells visited by the measured motion (of its first 5000 points): "
        + ", ".join(f"{z}: {n}" for z, n in report["published_P1_cells_visited"].items())
        + f"; {len(cells)} cells visited in all.",
        "",
    ]
    (args.out / "lyapunov_feng_yang.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
