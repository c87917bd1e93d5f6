"""Start-up cost of the command line with a warm numba cache: process wall time.

Runs, as separate processes, numba's own floor (a script that imports numba and loads
one cached ``njit`` function: what any process that runs compiled code pays, whatever
the package), ``python -c "import rubcosim.cli"`` (the interpreter, numba and the
package), ``rubcosim run scenarios/impact_oscillator_linear.toml --no-plots``
(a small scenario: 150 s of the linear impact oscillator on the ``fast`` engine, 48
impacts; the results and report written) and the same run with its three plots.  One
untimed run of each first, so the numba cache is warm and the files are in the page
cache; then ``--repeats`` runs of each, taken in turn, median with min-max.

The cold start, each once (minutes of compiling; ``--no-cold`` skips it), every time
with a new empty numba cache (``NUMBA_CACHE_DIR``): the small run with nothing
compiled (a first run of a model: it compiles its family's engine; issue 45's
target: <= 20 s), ``make run``'s two commands (the flagship on the ``accurate``
engine, then its ``check`` against a co-simulation; issue 45's target for all of
``make run`` on a fresh clone, set-up included: <= 2 min), ``rubcosim warm-up``
(every bundled model, in the scope in force) and the small run right after it.
Writes benchmarks/results/startup.{json,md}.

    .venv/bin/python benchmarks/bench_startup.py [--repeats 5] [--no-cold]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from stamp import REPO, stamp, stamp_line

RESULTS = REPO / "benchmarks" / "results"
SCENARIO = "scenarios/impact_oscillator_linear.toml"
TARGET_S = 0.8  # issue 45 (issue 15 asked 1 s): a warm run of a small scenario
COLD_TARGET_S = 20.0  # issue 45: a first run of a bundled scenario on an empty cache
MAKE_RUN_TARGET_S = 120.0  # issue 45: make run on a fresh clone, set-up included
FLAGSHIP = "scenarios/jeffcott_rigid_stator.toml"


def _timed(cmd: list[str], env: dict[str, str] | None = None) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, cwd=REPO, check=True, capture_output=True, env=env)
    return time.perf_counter() - start


def cold_start(out: Path) -> dict[str, float]:
    """Wall times (s), once each, with new empty numba caches: the small run, the
    warm-up, and the small run after the warm-up."""
    exe = str(Path(sys.executable).with_name("rubcosim"))
    run = [exe, "run", SCENARIO, "--out", str(out), "--no-progress", "--no-plots"]
    flagship = [exe, "run", FLAGSHIP, "--engine", "accurate", "--no-progress", "--no-plots"]
    check = [exe, "check", FLAGSHIP, "--no-progress", "--out", str(out / "check")]
    with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b, \
            tempfile.TemporaryDirectory() as c:  # fmt: skip
        cold = _timed(run, {**os.environ, "NUMBA_CACHE_DIR": a})
        env = {**os.environ, "NUMBA_CACHE_DIR": c}
        make_run = _timed([*flagship, "--out", str(out / "flagship")], env) + _timed(check, env)
        env = {**os.environ, "NUMBA_CACHE_DIR": b}
        warm_up = _timed([exe, "warm-up"], env)
        after = _timed(run, env)
    return {"run, empty cache": cold, "make run's run and check, empty cache": make_run,
            "rubcosim warm-up, empty cache": warm_up, "run after the warm-up": after}  # fmt: skip


FLOOR = """import numba


@numba.njit(cache=True)
def one_more(x):
    return x + 1.0


one_more(1.0)
"""
FLOOR_ROW = "numba's floor: load one cached function"


def commands(out: Path) -> dict[str, list[str]]:
    exe = str(Path(sys.executable).with_name("rubcosim"))
    run = [exe, "run", SCENARIO, "--out", str(out), "--no-progress"]
    floor = out.parent / "numba_floor.py"
    floor.write_text(FLOOR)
    return {
        FLOOR_ROW: [sys.executable, str(floor)],
        "import rubcosim.cli": [sys.executable, "-c", "import rubcosim.cli"],
        "rubcosim run --no-plots": [*run, "--no-plots"],
        "rubcosim run (3 plots)": run,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-start runs")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        cmds = commands(Path(tmp) / "out")
        walls: dict[str, list[float]] = {name: [] for name in cmds}
        for _ in range(args.repeats + 1):  # the first round is untimed
            for name, cmd in cmds.items():
                start = time.perf_counter()
                subprocess.run(cmd, cwd=REPO, check=True, capture_output=True)
                walls[name].append(time.perf_counter() - start)
    rows = {
        name: {"median_s": statistics.median(w[1:]), "min_s": min(w[1:]), "max_s": max(w[1:])}
        for name, w in walls.items()
    }
    with tempfile.TemporaryDirectory() as tmp:
        cold = {} if args.no_cold else cold_start(Path(tmp) / "cold")
    report = {
        "meta": stamp(repeats=args.repeats, scenario=SCENARIO),
        "runs": rows,
        "cold": cold,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "startup.json").write_text(json.dumps(report, indent=2) + "\n")
    warm = rows["rubcosim run --no-plots"]["median_s"]
    verdict = "met" if warm <= TARGET_S else "NOT met"
    lines = [
        "# Start-up: warm cache, and cold",
        "",
        f"Process wall time, median of {args.repeats} runs (min-max) after one untimed run "
        f"each; `{SCENARIO}` on its `fast` engine. " + stamp_line(report["meta"]),
        "",
        "| command | wall time |",
        "|---|---|",
    ]
    for name, r in rows.items():
        lines.append(f"| `{name}` | {r['median_s']:.2f} s ({r['min_s']:.2f}-{r['max_s']:.2f}) |")
    floor = rows[FLOOR_ROW]["median_s"]
    lines += ["", f"Target: a warm run of a small scenario <= {TARGET_S:g} s: {verdict} "
              f"without plots; the run takes {warm - floor:.2f} s more than numba's floor "
              f"({floor:.2f} s: importing numba, its CPU target's registries, which import "
              "scipy.linalg, and one cached function).", ""]  # fmt: skip
    if cold:
        first, make_run = cold["run, empty cache"], cold["make run's run and check, empty cache"]
        lines += [
            "Cold start: each once, every time with a new empty numba cache; "
            "`rubcosim run --no-plots` of the same scenario.",
            "",
            "| step | wall time |",
            "|---|---|",
            *(f"| {name} | {sec:.1f} s |" for name, sec in cold.items()),
            "",
            f"Target: a first run of a bundled scenario on an empty cache <= "
            f"{COLD_TARGET_S:g} s: {'met' if first <= COLD_TARGET_S else 'NOT met'} "
            f"({first:.1f} s).  `make run` on a fresh clone <= {MAKE_RUN_TARGET_S:g} s, "
            f"set-up included: its two commands alone take {make_run:.1f} s "
            f"({'within' if make_run <= MAKE_RUN_TARGET_S else 'over'} it before the "
            "set-up's venv and install).",
            "",
        ]
    (RESULTS / "startup.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
