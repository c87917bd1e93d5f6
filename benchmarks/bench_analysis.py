"""Performance of the analyses against the targets of the analyses issue.

- cell mapping: 200 x 200 cells x 16 samples (640,000 one-period maps) of the
  one-sided impact Duffing oscillator (``scenarios/impact_duffing.toml``),
  target <= 30 s on 2 cores;
- bifurcation diagram: 400 values x 300 forcing periods (100 discarded, 200
  kept) of the rigid-stator rotor (``scenarios/jeffcott_rigid_stator.toml``,
  speed 0.6 ... 1.6 wn), target <= 60 s on 2 cores.

Each is run ``--repeats`` times in one process after a warm-up (compiling or
loading the kernels is not counted), with ``--workers`` local processes; the
median wall time is reported.  Run from the repository root::

    .venv/bin/python benchmarks/bench_analysis.py [--quick] [--repeats 3] [--out DIR]

``--quick`` shrinks both problems 16-fold (a smoke run, not the targets).
Writes ``analysis.json`` and ``analysis.md`` to ``--out`` (default
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

from rubcosim.analysis.cellmap import Grid, cell_mapping
from rubcosim.analysis.maps import StroboscopicMap
from rubcosim.analysis.sweep import ParamRange, sweep
from rubcosim.scenario import load_scenario

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results"
WN = 316.227766  # natural frequency of the Jeffcott scenarios, rad/s


def bench_cells(n: int, samples: int, workers: int) -> dict[str, Any]:
    sc = load_scenario(REPO / "scenarios" / "impact_duffing.toml")
    smap = StroboscopicMap(sc.system, rtol=1e-7)
    grid = Grid(n, n, -3.0, 1.0, -6.0, 6.0)
    t0 = time.perf_counter()
    basins = cell_mapping(smap, grid, samples, seed=0, workers=workers)
    wall = time.perf_counter() - t0
    return {
        "wall_s": wall,
        "maps": n * n * samples,
        "attractors": [m["label"] for m in basins.motions],
        "counts": basins.counts(),
    }


def bench_sweep(count: int, discard: int, keep: int, workers: int) -> dict[str, Any]:
    sc = load_scenario(REPO / "scenarios" / "jeffcott_rigid_stator.toml")
    param = ParamRange("rotor.speed", 0.6 * WN, 1.6 * WN, count)
    t0 = time.perf_counter()
    res = sweep(
        sc,
        param,
        periods=keep,
        discard=discard,
        direction="up",
        rtol=1e-8,
        workers=workers,
        chains=workers,
    )
    wall = time.perf_counter() - t0
    labels = [c["label"] for c in res.classify("up")]
    return {
        "wall_s": wall,
        "values": count,
        "periods_per_value": discard + keep,
        "failed": int((res.status["up"] != 0).sum()),
        "labels": sorted(set(labels)),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--quick", action="store_true", help="16x smaller problems (smoke run)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error("--repeats must be >= 1")
    n, count = (50, 100) if args.quick else (200, 400)
    bench_cells(8, 2, args.workers)  # warm-up: load the kernels
    bench_sweep(2, 1, 2, 1)
    cells = [bench_cells(n, 16, args.workers) for _ in range(args.repeats)]
    sweeps = [bench_sweep(count, 100, 200, args.workers) for _ in range(args.repeats)]
    rows = {
        "cell_mapping": {
            "problem": f"{n}x{n} cells x 16 samples = {n * n * 16} one-period maps",
            "target_s": 30.0,
            "median_s": statistics.median(r["wall_s"] for r in cells),
            "runs_s": [r["wall_s"] for r in cells],
            "detail": cells[0],
        },
        "bifurcation": {
            "problem": f"{count} speeds x 300 periods, rigid-stator rotor",
            "target_s": 60.0,
            "median_s": statistics.median(r["wall_s"] for r in sweeps),
            "runs_s": [r["wall_s"] for r in sweeps],
            "detail": sweeps[0],
        },
    }
    meta = stamp(repeats=args.repeats, workers=args.workers, quick=args.quick)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "analysis.json").write_text(
        json.dumps({"meta": meta, "quick": args.quick, "workers": args.workers, **rows}, indent=1)
    )
    lines = ["| study | problem | median wall | runs | target | met |", "|---|---|---|---|---|---|"]
    for name, r in rows.items():
        runs = ", ".join(f"{t:.1f}" for t in r["runs_s"])
        met = "yes" if r["median_s"] <= r["target_s"] and not args.quick else "-"
        lines.append(
            f"| {name} | {r['problem']} | {r['median_s']:.1f} s | {runs} s "
            f"| {r['target_s']:.0f} s | {met} |"
        )
    md = "\n".join(
        [
            *lines,
            "",
            f"Medians of {args.repeats} runs after a warm-up, "
            f"{args.workers} worker processes. " + stamp_line(meta),
        ]
    )
    (args.out / "analysis.md").write_text(md + "\n")
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
