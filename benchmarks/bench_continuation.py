"""Continuation of impacting periodic orbits against the targets of the continuation issue.

- a 200-point branch of the impact Duffing oscillator (``scenarios/impact_duffing.toml``,
  its impacting period-1 orbit, forcing frequency 2.0 -> 3.5 with arclength steps of at
  most 0.012 of the range, so that it takes 200 points; its fold located), target <= 2 s
  on 2 cores with a warm cache;
- a two-parameter flip curve of 50 points: the flip of Feng & Yang's impacting orbit P4
  (``scenarios/feng_yang_attractors.toml``, started from the paper's P4 cell) followed in
  (forcing frequency, restitution) from R = 0.8 down, target <= 10 s;
- a basin continuation of Feng & Yang's case over 31 forcing amplitudes 0.6 ... 0.9 at
  100 x 100 cells x 4 samples (pursuit, 100 fates a value checked by direct simulation,
  two local workers), target <= 2 min; run once (``--basin-repeats``), after the others.

Each is run ``--repeats`` times in one process after a warm-up (compiling or loading the
kernels is not counted): medians with min-max.  Run from the repository root::

    .venv/bin/python benchmarks/bench_continuation.py [--repeats 5] [--out DIR]

Writes ``continuation.json`` and ``continuation.md`` to ``--out`` (default
``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

from stamp import stamp, stamp_line

import rubcosim as rc

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results"
PARAM = "oscillator.forcing_frequency"
P4_CELL_CENTRE = [0.9625, 0.33]  # Feng & Yang's P4, cell 23398 of their grid


def branch_run() -> tuple[float, dict[str, Any]]:
    sc = rc.load("impact_duffing")
    t0 = time.perf_counter()
    br = rc.continuation(sc, PARAM, None, 3.5, max_step=0.012, max_points=200)
    wall = time.perf_counter() - t0
    return wall, {
        "points": len(br.points),
        "special": [[s.kind, s.param] for s in br.special],
        "max_residual": max(p.residual for p in br.points),
    }


def curve_run() -> tuple[float, dict[str, Any]]:
    sc = rc.load("feng_yang_attractors")
    br = rc.continuation(sc, PARAM, None, 0.55, y0=P4_CELL_CENTRE)
    t0 = time.perf_counter()
    curve = rc.bifurcation_curve(
        br, "flip", "oscillator.restitution", 0.02, max_step=0.02, max_points=50
    )
    wall = time.perf_counter() - t0
    return wall, {
        "points": len(curve.points),
        "restitution": [float(curve.params2[0]), float(curve.params2[-1])],
        "frequency": [float(curve.params[0]), float(curve.params[-1])],
        "stop_reason": curve.stop_reason,
        "max_residual": max(p.residual for p in curve.points),
    }


def basin_run() -> tuple[float, dict[str, Any]]:
    import numpy as np

    t0 = time.perf_counter()
    res = rc.basin_continuation("feng_yang_attractors", "oscillator.forcing_amplitude",
                                np.linspace(0.6, 0.9, 31), (100, 100), 4, workers=2)  # fmt: skip
    wall = time.perf_counter() - t0
    rep = res.report()
    return wall, {"values": 31, "attractors": res.n_ids,
                  "events": sum(e["event"] != "present" for e in res.events),
                  "fates_checked": rep["fates_checked"],
                  "fates_agreeing": rep["fates_agreeing"]}  # fmt: skip


def basin_warmup() -> None:
    rc.basins("feng_yang_attractors", (10, 10), 1, check=1)  # the pursuit kernels loaded


def timed(run: Any, repeats: int, warmup: Any = None) -> dict[str, Any]:
    (warmup or run)()  # warm-up: kernels compiled or loaded
    walls, info = [], {}
    for _ in range(repeats):
        wall, info = run()
        walls.append(wall)
    return {"median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
            "repeats": repeats, **info}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--basin-repeats", type=int, default=1, help="0: no basin continuation")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    results = {
        "meta": stamp(repeats=args.repeats),
        "branch": {**timed(branch_run, args.repeats), "target_s": 2.0},
        "flip_curve": {**timed(curve_run, args.repeats), "target_s": 10.0},
    }
    if args.basin_repeats:
        results["basin_continuation"] = {
            **timed(basin_run, args.basin_repeats, basin_warmup),
            "target_s": 120.0,
        }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "continuation.json").write_text(json.dumps(results, indent=2) + "\n")
    b, c = results["branch"], results["flip_curve"]
    lines = [
        "| case | points | wall time, median (min-max) | target |",
        "|---|---:|---:|---:|",
        f"| impact Duffing, period-1 branch, fold located | {b['points']} | "
        f"{b['median_s']:.2f} s ({b['min_s']:.2f}-{b['max_s']:.2f}) | <= 2 s |",
        f"| Feng & Yang P4, flip curve in (w, R) | {c['points']} | "
        f"{c['median_s']:.2f} s ({c['min_s']:.2f}-{c['max_s']:.2f}) | <= 10 s |",
    ]
    if "basin_continuation" in results:
        bc = results["basin_continuation"]
        lines.append(
            f"| Feng & Yang basins at 31 amplitudes, 100 x 100 x 4 | {bc['values']} values "
            f"| {bc['median_s']:.1f} s ({bc['repeats']} run(s)) | <= 120 s |"
        )
    lines += [
        "",
        stamp_line(results["meta"]),
    ]
    (args.out / "continuation.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
