"""Feng & Yang's global structure, timed as a user runs it: the whole process.

``rubcosim basins feng_yang_attractors --out DIR`` (the scenario's ``[basins]``
table: pursuit, 200 x 200 cells x 16 samples over [-2, 1] x [-2, 2], the
paper's case) is started ``--repeats`` times as a separate process after one
warm-up run (compiled kernels cached: a warm cache), on ``--workers`` local
processes; the wall time of each process, start-up included, is read from
outside.  Target (issue 13): all four attractors and both saddles on the
paper's cells in <= 10 s on 2 cores.  Also recorded: the stages' seconds the
run reports (mapping, sample graph, attractors, trusted ties and tracking,
saddles), the basin counts against the paper's Table 1, the sample fractions.
Run from the repository root::

    .venv/bin/python benchmarks/bench_basins.py [--repeats 3] [--quick]

``--quick`` runs a 20 x 20 x 2 grid instead (a smoke run, not the target).
Writes ``basins_feng_yang.json`` and ``basins_feng_yang.md`` to ``--out``
(default ``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from rubcosim.analysis.published import found_label

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results"
TARGET_S = 10.0


def _run(extra: list[str], workers: int) -> tuple[float, dict[str, Any]]:
    """One process: its wall time (s) and its report.json."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "fy"
        cmd = [sys.executable, "-m", "rubcosim.cli", "basins", "feng_yang_attractors"]
        cmd += [*extra, "--workers", str(workers), "--no-progress", "--out", str(out)]
        t0 = time.monotonic()
        subprocess.run(cmd, cwd=REPO, check=True, capture_output=True)
        wall = time.monotonic() - t0
        return wall, json.loads((out / "report.json").read_text())


def _meta() -> dict[str, Any]:
    import numba
    import numpy as np
    import scipy

    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git_commit": commit,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "load_average_at_start": os.getloadavg()[0],
    }


def _markdown(res: dict[str, Any]) -> str:
    m, r = res["meta"], res["report"]
    pub = r.get("published", {})
    walls = res["wall_s"]
    lines = [
        "# Feng & Yang basins: process wall time and result",
        "",
        f"`{res['command']}`, {res['problem']}; {len(walls)} runs after {res['warmup']} "
        "untimed, "
        f"{res['workers']} workers.  {m['date']}, {m['cpu_count']} CPUs (load average "
        f"{m['load_average_at_start']:.1f} at the start: a shared machine), Python "
        f"{m['python']}, numpy {m['numpy']}, scipy {m['scipy']}, numba {m['numba']}, "
        f"commit {m['git_commit'][:10]}.",
        "",
        f"**Wall time: median {res['median_s']:.1f} s (min {min(walls):.1f}, max "
        f"{max(walls):.1f}); target {TARGET_S:.0f} s: {'met' if res['met'] else 'NOT met'}.**",
        "",
        "Stages of the first timed run (s): "
        + ", ".join(f"{k} {v:.1f}" for k, v in r["pursuit"]["seconds"].items())
        + f"; trusted ties: {json.dumps(r['pursuit'].get('ties', {}))}.",
        "",
        "| | paper cells | found (Hsu cells) | paper basin cells | found basin cells | samples |",
        "|---|---|---|---|---|---|",
    ]
    for a in pub.get("attractors", []):
        frac = a.get("sample_fraction") or 0.0
        lines.append(
            f"| {a['paper']} | {a['paper_cells']} | {found_label(a)} {a.get('cells')} "
            f"| {a['paper_basin_cells']} | {a.get('basin_cells')} | {100 * frac:.2f} % |"
        )
    for s in pub.get("saddles", []):
        mult = ", ".join(f"{complex(*z).real:.4g}" for z in s.get("multipliers", []))
        lines.append(f"| {s['paper']} | {s['paper_cells']} | {s.get('cell')} ({mult}) | | | |")
    b = pub.get("boundary_cells", {})
    lines.append(f"| boundary | | | {b.get('paper')} | {b.get('found')} | |")
    lines.append(
        f"| escape / sink | | | | {pub.get('escape_cells')} "
        f"| {100 * r['samples']['sink_fraction']:.2f} % |"
    )
    met = r.get("metrics", {})
    if "seconds" in met:
        e, b = met["basin_entropy"], met["boundary"]
        lines += [
            "",
            f"Basin metrics of the first timed run, computed in {met['seconds']:.2f} s "
            f"({100 * met['seconds'] / walls[0]:.1f} % of that run's {walls[0]:.1f} s): "
            f"Sb {e['Sb']:.4f}, Sbb {e['Sbb']:.4f} (ln 2 criterion: "
            f"{'fractal' if e['ln2_criterion_fractal'] else 'silent'}), boundary dimension "
            f"{b.get('dimension') or float('nan'):.3f}, uncertainty exponent "
            f"{b.get('uncertainty_exponent') or float('nan'):.3f}, "
            f"{'Wada' if met['wada'].get('wada') else 'not Wada'}.",
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--warmup", type=int, default=1, help="untimed runs first (a warm cache)")
    ap.add_argument("--quick", action="store_true", help="20 x 20 x 2 (a smoke run)")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.warmup < 0:
        ap.error("--repeats must be >= 1 and --warmup >= 0")
    extra = ["--grid", "20x20", "--samples", "2"] if args.quick else []
    meta = _meta()
    for _ in range(args.warmup):  # the compiled kernels' cache
        _run(extra, args.workers)
    runs = [_run(extra, args.workers) for _ in range(args.repeats)]
    walls = [w for w, _ in runs]
    report = runs[0][1]
    atts = report.get("published", {}).get("attractors", [])
    saddles = report.get("published", {}).get("saddles", [])
    found_all = (
        report["samples"]["total"] == 640_000
        and len(atts) == 4
        and all(set(a.get("cells") or []) & set(a["paper_cells"]) for a in atts)
        and all(s.get("cell") in s["paper_cells"] for s in saddles)
    )
    median = statistics.median(walls)
    res = {
        "meta": meta,
        "command": "rubcosim basins feng_yang_attractors " + " ".join(extra),
        "problem": "20 x 20 x 2 (quick)" if args.quick else "200 x 200 cells x 16 samples",
        "workers": args.workers,
        "warmup": args.warmup,
        "wall_s": walls,
        "median_s": median,
        "target_s": TARGET_S,
        "all_on_the_papers_cells": found_all,
        "met": bool(median <= TARGET_S and found_all and not args.quick),
        "report": {
            k: report[k]
            for k in ("pursuit", "counts", "samples", "published", "metrics")
            if k in report
        },
    }
    args.out.mkdir(parents=True, exist_ok=True)
    name = "basins_feng_yang_quick" if args.quick else "basins_feng_yang"
    (args.out / f"{name}.json").write_text(json.dumps(res, indent=1, default=str))
    md = _markdown(res)
    (args.out / f"{name}.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
