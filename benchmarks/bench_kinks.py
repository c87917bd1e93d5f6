"""A foreign FMU's kinks and jumps: located as events against left to error control.

The example oscillator_and_ball scenario (examples/foreign_fmu): the bouncing-ball FMU's
height (a kink at each bounce) or velocity (a jump) forcing the impact oscillator for
3 s, co-simulated with ``cosim.kinks = "locate"`` and ``"off"``.  Per case: macro steps
accepted and rejected, kinks located, probe steps, unit steps, the largest error of the
oscillator's displacement against scipy with the ball in closed form
(examples/foreign_fmu/ball_reference.py), and the wall time, median of ``--repeats``
runs with min-max.  Writes benchmarks/results/kinks.{json,md}.

    .venv/bin/python benchmarks/bench_kinks.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
from stamp import REPO, stamp, stamp_line

sys.path.insert(0, str(REPO / "examples" / "foreign_fmu"))
from ball_reference import driven_oscillator  # noqa: E402
from build import build  # noqa: E402

from rubcosim.orchestrator.assembly import run_cosim  # noqa: E402
from rubcosim.scenario import build_scenario  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
EXAMPLE = REPO / "examples" / "foreign_fmu" / "oscillator_and_ball.toml"
FIELDS = {"h": "height (kinks)", "v": "velocity (jumps)"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        build(Path(tmp) / "bouncing_ball.fmu")
        data = tomllib.loads(EXAMPLE.read_text())
        for field in FIELDS:
            data["connections"] = {"oscillator.force": [f"ball.{field}"]}
            sc = build_scenario(data, source=str(Path(tmp) / EXAMPLE.name))
            run_cosim(sc)  # warm-up
            x_ref = None
            for kinks in ("locate", "off"):
                settings = replace(sc.cosim, kinks=kinks)
                walls = []
                for _ in range(args.repeats):
                    start = time.perf_counter()
                    r = run_cosim(sc, settings=settings)
                    walls.append(time.perf_counter() - start)
                    assert r.ok, r.message
                if x_ref is None:
                    x_ref = driven_oscillator(r.t, field=field)
                c = r.counters
                rows.append(
                    {
                        "input": field,
                        "kinks": kinks,
                        "accepted": c["accepted"],
                        "rejected": c.get("rejected", 0),
                        "located": c.get("kinks", 0),
                        "kink_probes": c.get("kink_probes", 0),
                        "unit_steps": c["unit_steps"],
                        "max_error_x": float(np.max(np.abs(r.output("oscillator.x") - x_ref))),
                        "median_s": statistics.median(walls),
                        "min_s": min(walls),
                        "max_s": max(walls),
                    }
                )
    report = {"meta": stamp(repeats=args.repeats), "runs": rows}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "kinks.json").write_text(json.dumps(report, indent=2) + "\n")
    lines = [
        "# Kinks in a foreign FMU's output",
        "",
        "oscillator_and_ball, 3 s, the ball's output as the oscillator's force; error of x "
        "against scipy with the ball in closed form; wall time median of "
        f"{args.repeats} runs (min-max). " + stamp_line(report["meta"]),
        "",
        "| ball output | cosim.kinks | accepted | rejected | rejected / accepted | kinks "
        "located | probes | unit steps | max error of x | wall time |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for row in rows:
        lines.append(
            f"| {FIELDS[row['input']]} | {row['kinks']} | {row['accepted']} | {row['rejected']} "
            f"| {row['rejected'] / row['accepted']:.1%} | {row['located']} | "
            f"{row['kink_probes']} | {row['unit_steps']} | {row['max_error_x']:.1e} | "
            f"{row['median_s']:.3f} s ({row['min_s']:.3f}-{row['max_s']:.3f}) |"
        )
    lines.append("")
    (RESULTS / "kinks.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
