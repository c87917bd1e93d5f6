"""Work-precision benchmark of the co-simulation against the monolithic engines.

For four rotor scenarios (rigid stator, elastic stator on a casing, oil-film
bearing with rub, offset rigid stator with delayed velocity feedback) it measures
the error on the rotor displacement and the wall time of:

* ``accurate`` and ``fast``: the monolithic engines, rtol scanned in half decades;
* ``adaptive+events (compiled)``, ``adaptive+events (python)`` and
  ``adaptive+events (fmu)``: the master's default algorithm (Gauss-Seidel,
  extrapolation order 2, PI step control, events located by rollback) on the
  compiled master with in-process units, on the Python master with the same
  units, and on the Python master with our FMUs; ``cosim.rtol`` scanned in half
  decades;
* ``fixed+events``: the same algorithm with a fixed macro step (compiled master),
  step scanned;
* ``fixed Jacobi, no events``: the plain master most tools use: Jacobi,
  inputs held constant over a step, fixed step, and a contact seen only at
  the communication point after it happened (``cosim.events = "step"``),
  step scanned (compiled master).

Error: the largest difference of ``rotor.x`` and ``rotor.y`` from the
``accurate`` engine at rtol 1e-12 over the scenario's output grid, relative to
the largest |value| of the reference.  Wall time: the whole call (units built,
FMUs loaded), median of ``--repeats`` runs for runs under ``QUICK_S``
seconds, one run otherwise; one warm-up run per scenario and method family
first, so numba's cache loading is not counted.  A scan stops refining once a
run takes longer than ``--budget`` seconds.

The cost at equal error is the time of the cheapest run whose error is at or
below ``--target`` (1e-6): no interpolation, so it is an upper bound.

Run from the repository root (about 10 to 20 minutes on two cores)::

    .venv/bin/python benchmarks/bench_cosim.py
    .venv/bin/python benchmarks/bench_cosim.py --cases rigid --quick

It writes ``benchmarks/results/cosim_wp.{json,md,png}`` (``--out`` changes the
directory) and prints the table.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from stamp import git_commit, stamp, stamp_line

from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.runner import run_scenario
from rubcosim.scenario import Scenario, load_scenario
from rubcosim.timegrid import output_times

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results"
CASES = {
    "rigid": "jeffcott_rigid_stator.toml",
    "casing": "jeffcott_elastic_casing.toml",
    "oilfilm": "two_mass_oilfilm_rub.toml",
    "controller": "jeffcott_delayed_feedback.toml",
}
POSITIONS = ("rotor.x", "rotor.y")
REFERENCE_RTOL = 1e-12
QUICK_S = 2.0


@dataclass(frozen=True)
class Method:
    """A way to run a scenario: a label and the overrides for each scanned value."""

    name: str
    kind: str  # "engine" or "cosim"
    values: tuple[float, ...]  # scanned, cheapest (least accurate) first
    overrides: Callable[[float, float], list[str]]  # (value, period) -> --set overrides


def _steps(counts: tuple[int, ...]) -> tuple[float, ...]:
    return tuple(float(n) for n in counts)


def _half_decades(first: int, last: int) -> tuple[float, ...]:
    """1e-first, 3e-(first+1), 1e-(first+1), ..., 1e-last: loosest first."""
    out = [float(f"1e-{first}")]
    for k in range(first + 1, last + 1):
        out += [float(f"3e-{k}"), float(f"1e-{k}")]
    return tuple(out)


def methods(quick: bool) -> list[Method]:
    """The compared methods; ``quick`` scans two values each (for a smoke run)."""
    # tolerances in half decades (1 and 3 of each): the cost at the target error is the
    # cheapest run that meets it, so a coarser scan would overstate it by up to 10x
    rtols = _half_decades(5, 10)
    cosim_rtols = _half_decades(3, 7)
    fmu_rtols = cosim_rtols
    per_period = (100, 400, 1600, 6400, 25600)
    if quick:
        rtols, cosim_rtols, fmu_rtols, per_period = (
            rtols[:2], cosim_rtols[:2], fmu_rtols[:1], per_period[:2],
        )  # fmt: skip

    def engine(name: str) -> Callable[[float, float], list[str]]:
        return lambda v, _: [f"sim.engine={name}", f"sim.rtol={v!r}"]

    def fixed(extra: list[str]) -> Callable[[float, float], list[str]]:
        return lambda n, T: ["cosim.adaptive=false", f"cosim.step={T / n!r}", *extra]

    return [
        Method("accurate", "engine", rtols, engine("accurate")),
        Method("fast", "engine", rtols, engine("fast")),
        Method(
            "adaptive+events (compiled)",
            "cosim",
            cosim_rtols,
            lambda v, _: ["cosim.backend=direct", 'cosim.master="compiled"', f"cosim.rtol={v!r}"],
        ),
        Method(
            "adaptive+events (python)",
            "cosim",
            fmu_rtols,
            lambda v, _: ["cosim.backend=direct", 'cosim.master="python"', f"cosim.rtol={v!r}"],
        ),
        Method(
            "adaptive+events (fmu)",
            "cosim",
            fmu_rtols,
            lambda v, _: ["cosim.backend=fmu", f"cosim.rtol={v!r}"],
        ),
        Method("fixed+events", "cosim", _steps(per_period), fixed([])),
        Method(
            "fixed Jacobi, no events",
            "cosim",
            _steps(per_period),
            fixed(["cosim.algorithm=jacobi", "cosim.extrapolation=0", "cosim.events=step"]),
        ),
    ]


def displacement_error(ref: Any, values: Callable[[str], np.ndarray], rows: np.ndarray) -> float:
    """Largest |difference| of the rotor displacement over ``rows``, relative to the
    reference's largest |value|."""
    worst = 0.0
    for name in POSITIONS:
        a = ref.result.output(name)[rows]
        b = values(name)[rows]
        worst = max(worst, float(np.max(np.abs(a - b)) / np.max(np.abs(a))))
    return worst


def run_once(scenario: Scenario, kind: str, times: np.ndarray) -> tuple[Callable, float, dict]:
    """One run; returns (output lookup, wall time s, counters)."""
    wall = time.perf_counter()
    if kind == "engine":
        run = run_scenario(scenario)
        wall = time.perf_counter() - wall
        if not run.result.ok:
            raise RuntimeError(run.result.message)
        return run.result.output, wall, {"steps": int(run.result.counters.get("steps", 0))}
    result = run_cosim(scenario, record=list(POSITIONS), times=times)
    wall = time.perf_counter() - wall
    if not result.ok:
        raise RuntimeError(result.message)
    return result.output, wall, dict(result.counters)


def bench_case(case: str, args: argparse.Namespace, out: dict[str, Any]) -> dict[str, Any]:
    path = REPO / "scenarios" / CASES[case]
    base = load_scenario(path, [f"sim.rtol={REFERENCE_RTOL!r}"])
    period = base.system.forcing_period
    ref = run_scenario(base, engine="accurate")
    times, rows, _ = output_times(base)
    out.update(scenario=base.name, period_s=period)
    out.setdefault("methods", {})
    for method in methods(args.quick):
        if args.methods and method.name not in args.methods:
            continue
        points = []
        # a short run first: numba caches load and FMUs get built outside the timing
        warm = load_scenario(path, [*method.overrides(method.values[-1], period), "sim.t_end=0.01"])
        with contextlib.suppress(RuntimeError):  # the timed runs report their own failures
            run_once(warm, method.kind, output_times(warm)[0])
        for value in method.values:
            scenario = load_scenario(path, method.overrides(value, period))
            try:
                lookup, wall, counters = run_once(scenario, method.kind, times)
                walls = [wall]
                while wall < QUICK_S and len(walls) < args.repeats:
                    walls.append(run_once(scenario, method.kind, times)[1])
                err = displacement_error(ref, lookup, rows)
                point = {"value": value, "error": err, "wall_s": statistics.median(walls)}
                point["runs"] = len(walls)
                point["steps"] = counters.get("steps", 0)
                point["events"] = counters.get("events", 0)
                if "fmi_calls" in counters:
                    point["fmi_calls"] = counters["fmi_calls"]
            except RuntimeError as exc:
                point = {"value": value, "failed": str(exc)}
            points.append(point)
            print(f"{case:8s} {method.name:26s} {value:9.3g} {_describe(point)}", flush=True)
            if point.get("wall_s", 0.0) > args.budget:
                break
        out["methods"][method.name] = points
        # with --merge, methods may come from different commits: each says its own
        out.setdefault("measured_at", {})[method.name] = {"git_commit": git_commit()}
    return out


def cheapest_fmi_call(repeats: int = 5, calls: int = 2000) -> dict[str, float]:
    """Cost (s) of the cheapest call a master makes on an FMU every step: fmi2GetReal of
    one output of the rigid-stator FMU, through the backend's own direct path; median and
    range over ``repeats`` loops of ``calls`` calls.  Times the FMI calls per step, it is
    what the FMU backend costs per step before any work is done."""
    from rubcosim.orchestrator.assembly import fmu_paths
    from rubcosim.orchestrator.fmu_unit import FmuUnit

    path = fmu_paths({"stator": "rigid"}, None)["stator"]
    costs = []
    with FmuUnit(path) as fmu:
        fmu.get_values(["gap"])  # the call made once, outside the timing
        for _ in range(repeats):
            start = time.perf_counter()
            for _ in range(calls):
                fmu.get_values(["gap"])
            costs.append((time.perf_counter() - start) / calls)
    return {"median_s": statistics.median(costs), "min_s": min(costs), "max_s": max(costs)}


def _describe(point: dict[str, Any]) -> str:
    if "failed" in point:
        return f"failed: {point['failed']}"
    return f"error {point['error']:.2e}  wall {point['wall_s']:.3f} s  steps {point['steps']}"


def cost_at(points: list[dict[str, Any]], target: float) -> dict[str, Any] | None:
    """The cheapest run with an error at or below ``target``, or None."""
    good = [p for p in points if "error" in p and p["error"] <= target]
    return min(good, key=lambda p: p["wall_s"]) if good else None


def table(results: dict[str, Any], target: float) -> str:
    lines = [
        f"| case | method | wall time at error <= {target:g} | setting | error | best error |",
        "|---|---|---|---|---|---|",
    ]
    for case, res in results.items():
        for name, points in res["methods"].items():
            hit = cost_at(points, target)
            errors = [p["error"] for p in points if "error" in p]
            best = f"{min(errors):.1e}" if errors else "failed"
            if hit is None:
                lines.append(f"| {case} | {name} | not reached | | | {best} |")
            else:
                lines.append(
                    f"| {case} | {name} | {hit['wall_s']:.3f} s | {hit['value']:g} | "
                    f"{hit['error']:.1e} | {best} |"
                )
    return "\n".join(lines)


def ratios(
    results: dict[str, Any], target: float, call: dict[str, float] | None = None
) -> list[str]:
    """The targets of the issue, per case: the compiled co-simulation against
    ``accurate`` (<= 3x), the FMU backend against the compiled co-simulation (<= 5x),
    with the FMU backend's floor from ``call`` (:func:`cheapest_fmi_call`)."""
    lines = []
    for case, res in results.items():
        cost = {n: cost_at(p, target) for n, p in res["methods"].items()}
        ada, acc = cost.get("adaptive+events (compiled)"), cost.get("accurate")
        py, fmu = cost.get("adaptive+events (python)"), cost.get("adaptive+events (fmu)")
        plain = cost.get("fixed Jacobi, no events")
        parts = [f"{case}:"]
        if ada and acc:
            parts.append(
                f"compiled co-simulation / accurate = {ada['wall_s'] / acc['wall_s']:.1f}x;"
            )
        if ada and py:
            parts.append(f"Python master / compiled = {py['wall_s'] / ada['wall_s']:.1f}x;")
        if ada and fmu:
            parts.append(f"FMU backend / compiled = {fmu['wall_s'] / ada['wall_s']:.1f}x;")
            if fmu.get("fmi_calls") and call:
                floor = fmu["fmi_calls"] * call["median_s"]
                parts.append(
                    f"{fmu['fmi_calls'] / fmu['steps']:.1f} FMI calls per macro step, whose "
                    f"floor (calls x the cheapest call, {call['median_s'] * 1e6:.1f} us) "
                    f"alone is {floor / ada['wall_s']:.0f}x the compiled run;"
                )
        if ada and plain:
            parts.append(f"plain Jacobi / adaptive = {plain['wall_s'] / ada['wall_s']:.1f}x")
        elif ada:
            parts.append("plain Jacobi did not reach the target error")
        lines.append(" ".join(parts))
    return lines


def plot(results: dict[str, Any], target: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(5.2 * len(results), 4.4), squeeze=False)
    for ax, (case, res) in zip(axes[0], results.items(), strict=True):
        for name, points in res["methods"].items():
            good = [p for p in points if "error" in p]
            if good:
                ax.loglog(
                    [p["wall_s"] for p in good], [p["error"] for p in good], "o-", ms=4, label=name
                )
        ax.axhline(target, color="0.5", lw=0.8, ls=":")
        ax.set_title(f"{case} ({res['scenario']})", fontsize=9)
        ax.set_xlabel("wall time [s]")
        ax.set_ylabel("max relative error of rotor x, y")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=list(CASES))
    parser.add_argument("--repeats", type=int, default=3, help="runs per point (quick runs)")
    parser.add_argument("--budget", type=float, default=60.0, help="s; stop refining after")
    parser.add_argument("--target", type=float, default=1e-6, help="relative error target")
    parser.add_argument("--quick", action="store_true", help="two points per method")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    names = [m.name for m in methods(False)]
    parser.add_argument("--methods", nargs="+", choices=names, help="only these (default: all)")
    parser.add_argument("--merge", action="store_true", help="update the results already in --out")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.budget <= 0.0 or not 0.0 < args.target < 1.0:
        parser.error("--repeats must be >= 1, --budget > 0 and 0 < --target < 1")
    args.out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {}
    if args.merge and (args.out / "cosim_wp.json").exists():
        results = json.loads((args.out / "cosim_wp.json").read_text())["cases"]
    meta = stamp(target=args.target, repeats=args.repeats, quick=args.quick)
    call = None
    if not args.methods or "adaptive+events (fmu)" in args.methods:
        call = cheapest_fmi_call()
        meta["cheapest_fmi_call_s"] = call
    for case in args.cases:
        bench_case(case, args, results.setdefault(case, {}))
        # saved after every case: an interrupted run keeps what it measured (see --merge)
        text = json.dumps({"meta": meta, "cases": results}, indent=1)
        (args.out / "cosim_wp.json").write_text(text)
    md = (
        stamp_line(meta)
        + "\n\n"
        + table(results, args.target)
        + "\n\n"
        + "\n".join(f"- {r}" for r in ratios(results, args.target, call))
    )
    (args.out / "cosim_wp.md").write_text(md + "\n")
    plot(results, args.target, args.out / "cosim_wp.png")
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
