"""Stress tests of the co-simulation master: what was run and what happened.

Each case is a scenario with ``--set`` overrides, co-simulated with the
default master (Gauss-Seidel, extrapolation 2, adaptive, events located)
and, where the monolithic engines can run it, compared with ``accurate``
at rtol 1e-12 on the rotor displacement.  A case passes when the run ends
the way it should: completes with a finite state, or, for a model that is
truly unstable, stops with an error that names the unit, the signal and
the time.  Nothing here is timed against a target; wall times are one run
each.

Run from the repository root (a few minutes)::

    .venv/bin/python benchmarks/stress_cosim.py [--only NAME ...] [--long] [--out DIR]

``--long`` adds the 10,000-period run of the offset rigid stator (about 3 minutes on
the compiled master, 25 on the Python one; ``make bench`` runs it).

It writes ``stress.json`` and ``stress.md`` to ``--out`` (default
``benchmarks/results``) and prints the table.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from bench_cosim import POSITIONS, displacement_error
from stamp import stamp

from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.runner import run_scenario
from rubcosim.scenario import load_scenario
from rubcosim.timegrid import output_times

REPO = Path(__file__).resolve().parents[1]
SC = REPO / "scenarios"
DEFAULT_OUT = REPO / "benchmarks" / "results"
K = 1.0e6  # shaft stiffness of the Jeffcott scenarios, N/m
WN = 316.227766  # their natural frequency, rad/s


@dataclass(frozen=True)
class Case:
    name: str
    what: str
    scenario: Path
    overrides: tuple[str, ...]
    expect: str  # "ok" or "unstable"
    compare: bool = True
    long: bool = False  # run only with --long (tens of minutes on the Python master)


def cases() -> list[Case]:
    elastic = SC / "jeffcott_elastic_stator.toml"
    rigid = SC / "jeffcott_rigid_stator.toml"
    out = [
        Case(
            f"kc/k={ratio:g}",
            f"penalty stator, contact stiffness {ratio:g} k, friction 0.02, 0.2 s",
            elastic,
            (f"stator.contact_stiffness={ratio * K!r}", "sim.t_end=0.2"),
            "ok",
        )
        for ratio in (1e1, 1e3, 1e5, 1e7)
    ]
    out += [
        Case(
            f"speed={s:g} wn",
            f"rigid stator at {s:g} times the critical speed, 0.1 s",
            rigid,
            (f"rotor.speed={s * WN!r}", "sim.t_end=0.1"),
            "ok",
        )
        for s in (2.0, 5.0)
    ]
    out += [
        Case(
            "near grazing",
            "rigid stator, speed 0.821 wn, just above the rub onset 0.8206 wn: grazing contacts",
            rigid,
            (f"rotor.speed={0.821 * WN!r}", "sim.t_end=0.5"),
            "ok",
        ),
        Case(
            "chattering",
            "flagship: impacts accumulate (chattering), then sustained sliding, 0.5 s",
            rigid,
            (),
            "ok",
        ),
        Case(
            "1e4 periods",
            "offset rigid stator, 10,000 forcing periods (165 s) at cosim.rtol = 1e-4, "
            "output every 10 periods",
            SC / "jeffcott_offset_rigid_stator.toml",
            ("sim.t_end=165.6", "sim.output_step=0.1656", "cosim.rtol=1e-4"),
            "ok",
            compare=False,
            long=True,
        ),
        Case(
            "mixed FMU/direct",
            "flagship with the rigid stator as an FMU (through fmpy) and the rotor in-process, "
            "0.1 s",
            rigid,
            ('cosim.fmu_units=["stator"]', "sim.t_end=0.1"),
            "ok",
        ),
        Case(
            "unstable: backward whirl",
            "deep penalty contact (clearance 1e-7 m), beta = 20, friction 0.3: "
            "mu beta = 6 > 2 z sqrt(1 + beta) = 0.46, 0.1 s",
            elastic,
            ("stator.friction=0.3", "stator.clearance=1e-7", "sim.t_end=0.1"),
            "unstable",
        ),
    ]
    return out


def run_case(case: Case) -> dict[str, Any]:
    sc = load_scenario(case.scenario, list(case.overrides))
    times, rows, _ = output_times(sc)
    wall = time.perf_counter()
    co = run_cosim(sc, record=list(POSITIONS), times=times)
    wall = time.perf_counter() - wall
    row: dict[str, Any] = {
        "meta": stamp(),
        "case": case.name,
        "what": case.what,
        "expect": case.expect,
        "status": co.status,
        "message": co.message,
        "t_reached": co.t_reached,
        "t_end": sc.sim["t_end"],
        "wall_s": wall,
        "steps": co.counters.get("steps", 0),
        "events": co.counters.get("events", 0),
        "finite": bool(np.all(np.isfinite(co.values))),
    }
    if case.compare:
        ref = run_scenario(sc, engine="accurate")
        row["reference_status"] = "ok" if ref.result.ok else ref.result.message
        n = min(len(co.t), ref.result.t.size)
        r = rows[rows < n]
        if r.size and ref.result.ok and co.ok:
            row["rel_error"] = displacement_error(ref, co.output, r)
    if case.expect == "ok":
        row["passed"] = co.ok and row["finite"]
    else:
        row["passed"] = co.status == "failed" and "unstable" in co.message
    return row


def table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| case | what | outcome | t reached / t_end | steps | events | error vs accurate "
        "| wall | as expected |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        outcome = "completed" if r["status"] == "ok" else f"stopped: {r['message']}"
        err = f"{r['rel_error']:.1e}" if "rel_error" in r else "-"
        lines.append(
            f"| {r['case']} | {r['what']} | {outcome} | {r['t_reached']:.4g} / {r['t_end']:.4g} s "
            f"| {r['steps']} | {r['events']} | {err} | {r['wall_s']:.1f} s "
            f"| {'yes' if r['passed'] else 'NO'} |"
        )
    commits = sorted({r["meta"]["git_commit"][:10] for r in rows if "meta" in r})
    dates = sorted(r["meta"]["date"][:10] for r in rows if "meta" in r)
    if commits:
        lines.append(
            f"\nOne run per case, {dates[0]} to {dates[-1]}, at commit(s) {', '.join(commits)}."
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    names = [c.name for c in cases()]
    parser.add_argument("--only", nargs="+", choices=names, help="run only these cases")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    parser.add_argument(
        "--merge", action="store_true", help="keep the other cases of an earlier stress.json"
    )
    parser.add_argument(
        "--long", action="store_true", help="also the long cases (10,000 periods: ~25 min)"
    )
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    saved = args.out / "stress.json"
    kept = {r["case"]: r for r in json.loads(saved.read_text())} if args.merge else {}
    done = []
    for case in cases():
        if args.only and case.name not in args.only:
            continue
        if case.long and not (args.long or (args.only and case.name in args.only)):
            continue
        r = run_case(case)
        kept[r["case"]] = r
        done.append(r)
        print(f"{r['case']:28s} {r['status']:7s} {r['wall_s']:7.1f} s  {r['message']}", flush=True)
        rows = [kept[c.name] for c in cases() if c.name in kept]
        saved.write_text(json.dumps(rows, indent=1))  # after every case: long runs
        (args.out / "stress.md").write_text(table(rows) + "\n")
    print(table(rows))
    return 0 if all(r["passed"] for r in done) else 1


if __name__ == "__main__":
    raise SystemExit(main())
