"""Every benchmark whose figures the README or BENCHMARKS.md quotes: how to run it, the
results it writes, and the code it measures.

``make bench`` runs them all (``python benchmarks/catalog.py run``) and then copies
their tables into the documents (:mod:`readme_tables`).  ``tests/test_benchmark_figures.py``
fails when a results file was measured at a commit older than the last change to the
code it measures, or when a document's copy of a table differs from its results file.

Run from the repository root::

    .venv/bin/python benchmarks/catalog.py list         # what is stale, and why
    .venv/bin/python benchmarks/catalog.py run [NAME ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"

ENGINES = ("components", "rubcosim/reference")
ANALYSES = (*ENGINES, "rubcosim/analysis")
COSIM = (*ENGINES, "orchestrator", "fmus")


@dataclass(frozen=True)
class Benchmark:
    """``name``: the stem of its results files (``results/NAME.json`` and ``.md``);
    ``command``: its script and arguments; ``measures``: folders whose changes make
    its figures stale."""

    name: str
    command: tuple[str, ...]
    measures: tuple[str, ...]


BENCHMARKS = (
    Benchmark("engines", ("bench_engines.py", "--periods", "200"), ENGINES),
    Benchmark("analysis", ("bench_analysis.py", "--repeats", "3"), ANALYSES),
    Benchmark("basins_feng_yang", ("bench_basins.py", "--repeats", "3"), ANALYSES),
    Benchmark("lyapunov_feng_yang", ("study_lyapunov.py",), ANALYSES),
    Benchmark("basin_fates", ("verify_basin_fates.py",), ANALYSES),
    Benchmark("continuation", ("bench_continuation.py", "--repeats", "5"), ANALYSES),
    Benchmark("cosim_wp", ("bench_cosim.py",), COSIM),
    Benchmark("stress", ("stress_cosim.py", "--long"), COSIM),
    Benchmark("isolation", ("bench_isolation.py",), COSIM),
    Benchmark("fmu_step", ("bench_fmu_step.py",), COSIM),
    Benchmark("kinks", ("bench_kinks.py",), COSIM),
    Benchmark("startup", ("bench_startup.py",), ("components", "rubcosim", "orchestrator")),
)


def commits_in(data: Any) -> Iterator[str]:
    """Every ``git_commit`` a results file records (one per run when runs were merged)."""
    if isinstance(data, dict):
        for key, value in data.items():
            if key == "git_commit" and isinstance(value, str):
                yield value.removesuffix("+dirty")
            else:
                yield from commits_in(value)
    elif isinstance(data, list):
        for value in data:
            yield from commits_in(value)


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.strip()


def staleness(bench: Benchmark, results: Path = RESULTS) -> list[str]:
    """Why ``bench``'s figures cannot be trusted at HEAD; empty when they can.

    A figure is stale when it names no commit, a commit this history does not hold, or
    one followed by commits that change what the benchmark measures."""
    path = results / f"{bench.name}.json"
    if not path.exists():
        return [f"{path.name} is missing (run benchmarks/{' '.join(bench.command)})"]
    commits = sorted(set(commits_in(json.loads(path.read_text()))))
    if not commits:
        return [f"{path.name} records no git_commit"]
    reasons = []
    for commit in commits:
        try:
            _git("cat-file", "-e", f"{commit}^{{commit}}")
        except subprocess.CalledProcessError:
            reasons.append(f"{path.name}: commit {commit[:10]} is not in this history")
            continue
        later = _git("rev-list", f"{commit}..HEAD", "--", *bench.measures).split()
        if later:
            reasons.append(
                f"{path.name}: measured at {commit[:10]}; {len(later)} later commit(s) change "
                f"{', '.join(bench.measures)} (the newest {later[0][:10]})"
            )
    return reasons


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    sub = parser.add_subparsers(dest="action", required=True)
    sub.add_parser("list", help="each benchmark and whether its figures are current")
    run = sub.add_parser("run", help="run benchmarks (all, or the ones named)")
    run.add_argument("names", nargs="*", help=", ".join(b.name for b in BENCHMARKS))
    run.add_argument("--stale", action="store_true", help="only the stale ones")
    args = parser.parse_args(argv)
    unknown = set(getattr(args, "names", [])) - {b.name for b in BENCHMARKS}
    if unknown:
        parser.error(f"unknown benchmark(s): {', '.join(sorted(unknown))}")
    if args.action == "list":
        for bench in BENCHMARKS:
            reasons = staleness(bench)
            print(f"{bench.name:20s} {'STALE' if reasons else 'current'}")
            for r in reasons:
                print(f"    {r}")
        return 0
    failed = []
    for bench in BENCHMARKS:
        if args.names and bench.name not in args.names:
            continue
        if args.stale and not staleness(bench):
            continue
        cmd = [sys.executable, str(REPO / "benchmarks" / bench.command[0]), *bench.command[1:]]
        print(f"== {bench.name}: {' '.join(cmd[1:])}", flush=True)
        if subprocess.run(cmd, cwd=REPO).returncode != 0:
            failed.append(bench.name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
