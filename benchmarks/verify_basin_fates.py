"""Feng & Yang's basins, sample by sample, against direct simulation.

Runs :func:`rubcosim.basins` on the paper's case (``feng_yang_attractors``: its
``[basins]`` table, 200 x 200 cells x 16 samples), draws ``--draw`` random samples
whose fate is one of the attractors (not the sink), simulates each of them
``--periods`` forcing periods at ``--rtol`` with the compiled map, and classifies it
by where it ends (:func:`rubcosim.analysis.fate_check.classify`, the check every basins
result gets, here on many more samples): within ``AT_ORBIT`` state scales of a point
of a periodic attractor's orbit on the section, that attractor; otherwise the
attractor that is not periodic.  Reports how
many fates agree and lists the ones that do not.  Run from the repository root::

    .venv/bin/python benchmarks/verify_basin_fates.py [--draw 10000] [--periods 1000]

Writes ``basin_fates.json`` and ``basin_fates.md`` to ``--out`` (default
``benchmarks/results``).
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from stamp import stamp, stamp_line

import rubcosim as rc
from rubcosim.analysis.cellmap import CELL_MAP_RTOL, all_samples
from rubcosim.analysis.fate_check import classify
from rubcosim.analysis.maps import StroboscopicMap

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results"
SCENARIO = "feng_yang_attractors"


def _ends(args: tuple[np.ndarray, int, float]) -> tuple[np.ndarray, np.ndarray]:
    """Where each state is after ``periods`` forcing periods, and the run's status."""
    states, periods, rtol = args
    smap = StroboscopicMap(rc.load(SCENARIO).system, rtol)
    ends, _, _, status = smap.map(states, periods=periods)
    return ends, status


def _markdown(res: dict[str, Any]) -> str:
    bad = res["disagree"]
    lines = [
        "# Feng & Yang's basins: each sample's fate against direct simulation",
        "",
        f'`rubcosim.basins("{SCENARIO}")` (200 x 200 cells x 16 samples, seed 0, '
        f"rtol {res['basins_rtol']:g}); {res['draw']} random samples not sent to the sink "
        f"(draw seed {res['seed']}), each simulated {res['periods']} periods at rtol "
        f"{res['rtol']:g} and classified by where it ends.  {stamp_line(res['meta'])}",
        "",
        f"**{res['agree']} of {res['draw']} agree ({100.0 * res['agree'] / res['draw']:.2f} %).**"
        f"  Basins in {res['basins_s']:.1f} s, direct simulations in {res['direct_s']:.1f} s.",
    ]
    if bad:
        lines += ["", "| sample | x | x' | pursuit | direct |", "|---:|---:|---:|---|---|"]
        lines += [
            f"| {b['sample']} | {b['x']:.5f} | {b['v']:.5f} | {b['pursuit']} | {b['direct']} |"
            for b in bad
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--draw", type=int, default=10000, help="samples checked")
    ap.add_argument("--periods", type=int, default=1000)
    ap.add_argument("--rtol", type=float, default=1e-9, help="of the direct simulations")
    ap.add_argument("--seed", type=int, default=3, help="of the draw")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    if args.draw < 1 or args.periods < 1 or args.workers < 1:
        ap.error("--draw, --periods and --workers must be >= 1")
    meta = stamp(draw=args.draw, periods=args.periods, rtol=args.rtol, seed=args.seed)
    t0 = time.perf_counter()
    b = rc.basins(SCENARIO, workers=args.workers)
    t1 = time.perf_counter()
    fates = b.fates.ravel()
    # the samples as pursuit draws them: task by task (each task's own random stream)
    points = all_samples(b.grid, b.samples, b.seed)
    rng = np.random.default_rng(args.seed)
    pick = rng.choice(np.flatnonzero(fates < b.n_attractors), args.draw, replace=False)
    chunks = np.array_split(pick, args.workers)
    with ProcessPoolExecutor(args.workers) as pool:
        parts = list(pool.map(_ends, [(points[c], args.periods, args.rtol) for c in chunks]))
    t2 = time.perf_counter()
    ends = np.concatenate([e for e, _ in parts])
    failed = int(np.sum(np.concatenate([s for _, s in parts]) != 0))
    direct = classify(ends, b.motions, StroboscopicMap(rc.load(SCENARIO).system, args.rtol).scale)
    labels = [f"{k + 1}: {m['label']}" for k, m in enumerate(b.motions)]
    wrong = np.flatnonzero(direct != fates[pick])
    res = {
        "meta": meta,
        "draw": args.draw,
        "periods": args.periods,
        "rtol": args.rtol,
        "seed": args.seed,
        "basins_rtol": CELL_MAP_RTOL,
        "basins_s": t1 - t0,
        "direct_s": t2 - t1,
        "failed_runs": failed,
        "agree": int(args.draw - wrong.size),
        "ties": b.info["pursuit"]["ties"],
        "disagree": [
            {
                "sample": int(pick[i]),
                "x": float(points[pick[i], 0]),
                "v": float(points[pick[i], 1]),
                "pursuit": labels[fates[pick[i]]],
                "direct": labels[direct[i]] if direct[i] >= 0 else "none",
            }
            for i in wrong
        ],
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "basin_fates.json").write_text(json.dumps(res, indent=1, default=str))
    md = _markdown(res)
    (args.out / "basin_fates.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
