"""Cost of running a foreign FMU isolated in a worker process (``isolate = true``).

The example rotor-and-ball scenario (examples/foreign_fmu: the flagship rotor and
stator in-process, the bouncing-ball FMU through fmpy) is co-simulated with the
ball in this process and in a worker process; the difference of wall time per
macro step, once the worker's start-up (timed apart: spawning it, importing
rubcosim there, loading the FMU) is taken off, is the cost of isolation per step
(every FMI call of the ball becomes a round trip through a pipe).  Median of
``--repeats`` runs each, with min-max, taken in alternation.  Writes
benchmarks/results/isolation.{json,md}.

    .venv/bin/python benchmarks/bench_isolation.py [--repeats 5] [--t-end 0.02]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from stamp import REPO, stamp, stamp_line

sys.path.insert(0, str(REPO / "examples" / "foreign_fmu"))
from build import build  # noqa: E402

from rubcosim.orchestrator.assembly import run_cosim  # noqa: E402
from rubcosim.orchestrator.isolated_fmu import IsolatedFmu  # noqa: E402
from rubcosim.scenario import load_scenario  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--t-end", type=float, default=0.02, help="simulated time (s)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        toml = Path(tmp) / "rotor_and_ball.toml"
        toml.write_text((REPO / "examples/foreign_fmu/rotor_and_ball.toml").read_text())
        build(Path(tmp) / "bouncing_ball.fmu")
        sc = load_scenario(toml, [f"sim.t_end={args.t_end}"])
        times: dict[str, list[float]] = {"in-process": [], "isolated": [], "start-up": []}
        steps = {}
        run_cosim(sc)  # warm-up: compiled kernels, the FMU extracted once
        for _ in range(args.repeats):
            for kind, isolate in (("in-process", False), ("isolated", True)):
                start = time.perf_counter()
                r = run_cosim(sc, settings=replace(sc.cosim, isolate=isolate))
                times[kind].append(time.perf_counter() - start)
                assert r.ok, r.message
                steps[kind] = r.counters["steps"]
            start = time.perf_counter()
            IsolatedFmu(sc.fmus["ball"].path, name="ball", params=sc.fmus["ball"].start).close()
            times["start-up"].append(time.perf_counter() - start)
            steps["start-up"] = 0
    rows = {
        k: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v), "steps": steps[k]}
        for k, v in times.items()
    }
    extra = rows["isolated"]["median_s"] - rows["in-process"]["median_s"]
    per_step = (extra - rows["start-up"]["median_s"]) / steps["isolated"]
    report = {
        "meta": stamp(repeats=args.repeats, t_end=args.t_end),
        "runs": rows,
        "isolation_cost_per_macro_step_s": per_step,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "isolation.json").write_text(json.dumps(report, indent=2) + "\n")
    lines = [
        "# Isolated FMU: cost per macro step",
        "",
        f"rotor_and_ball, {args.t_end} s, median of {args.repeats} runs (min-max). "
        + stamp_line(report["meta"]),
        "",
        "| ball FMU | wall time | macro steps |",
        "|---|---:|---:|",
    ]
    for kind, row in rows.items():
        lines.append(
            f"| {kind} | {row['median_s']:.3f} s ({row['min_s']:.3f}-{row['max_s']:.3f}) "
            f"| {row['steps']} |"
        )
    lines += [
        "",
        f"Isolation costs {rows['start-up']['median_s']:.2f} s to start the worker, then "
        f"{per_step * 1e6:.0f} us per macro step.",
        "",
    ]
    (RESULTS / "isolation.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
