"""Engine benchmark: wall time per forcing period at equal accuracy.

Measures three integrators of the same nonsmooth models:

* ``fast``: the numba-compiled event-driven DOP853 engine (``simulate(engine="fast")``);
* ``accurate``: the scipy DOP853 stepper driven by the shared event machinery
  (``simulate(engine="accurate")``);
* ``scipy loop``: what a typical user would write, a ``scipy.integrate.solve_ivp``
  (DOP853) call with a terminal event on the gap (``gap = 0``, direction -1),
  restarted after every event with the impact map applied; its right-hand side is a
  Python function that calls the component kernels (``jeffcott_force``,
  ``free_acceleration``) and its impact map calls ``rigid_impact`` /
  ``impact_velocity``.  It has no notion of sustained contact or sticking, so the
  cases below are chosen so that the motion keeps impacting and never settles.

The cases, their scipy loops and one timed run are in ``engine_cases.py``; the floor
below in ``engine_floor.py``; this script scans the tolerances, times the runs and
writes the tables.

Cases (both start on their attractor, a stable period-1 impacting orbit, found by a
settling run from rest, so every period costs the same and integration errors do not
grow):

* ``rotor``: the flagship Jeffcott rotor (z = 0.05, e/d = 0.5, speed ratio 1.2) on a
  rigid stator offset by 0.8 clearances along x, restitution 0.8, friction 0.05:
  three impacts per period, no sliding or sticking.
* ``duffing``: the impact Duffing oscillator x'' + 0.1 x' + x + x^3 = cos(1.2 t) with a
  rigid one-sided barrier at x = 0.3, restitution 0.8: one impact per period.

Equal accuracy: the trusted reference is ``simulate(engine="accurate", rtol=1e-12)``.
The error of a run is the largest deviation of its positions from the reference on a
stroboscopic grid (t = k T, k = 0..periods), each position normalised by the largest
absolute value of its reference output.  For each integrator rtol is scanned from 1e-6
to 1e-12 in half decades (atol = rtol times the state scale of the system: clearance
for displacements, clearance times frequency for velocities, the engines' own
convention); the loosest rtol is kept whose error is <= the target (1e-8) and whose next
tighter rtol passes too (so that a lucky cancellation is not picked).

Timing: at that rtol, one warm-up run (numba compilation excluded), then the median of
at least ``--repeats`` runs (more for runs that take milliseconds, up to ~0.3 s of
runs).  The wall time covers the whole call (``simulate(...)`` or the scipy loop).

The floor of ``fast`` (issue: "within 2x of its right-hand-side floor"): its
right-hand-side calls per period times the cost of one compiled call, measured in a
compiled loop of calls spread over a forcing period; the ratio of ``fast``'s time to
that floor is what its step control, event location and bookkeeping add.  The ratio
is taken in rounds (``--floor-rounds``): one ``fast`` run, then at once a loop of as
many calls as that run made; its figure is the median of the rounds' ratios, so this
machine's drift over the seconds between the timed runs and the loops cancels.  The
calls of that loop are independent, so the processor overlaps them (the forcing's
``cos`` of one call with the arithmetic of the next); the stages of a step cannot
overlap, each waiting for the ones before.  So a second floor is printed beside it,
from a loop of calls that each wait for the one before (in the same rounds); the
target stays judged on the first.  Last, the same distance on the same model with the
obstacle out of reach (``Case.out_of_reach``: settled there, at the impacting run's
rtol): the step loop alone, so that the impacting case's distance splits into the step
loop and what its events add.

Run from the repository root::

    .venv/bin/python benchmarks/bench_engines.py
    .venv/bin/python benchmarks/bench_engines.py --periods 50 --repeats 5 --out /tmp/e.json

It writes a JSON file (``--out``, default ``benchmarks/results/engines.json``) and a
Markdown table (``--md``, default ``benchmarks/results/engines.md``), and prints the
table.  It takes well under a minute (about 15 s on two idle cores; the settling and
reference runs and the rtol scans are included).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from engine_cases import CASES, MAX_EVENTS, Case, Run, max_error, run_once, settle
from engine_floor import call_cost, floor_rounds, free_flight
from stamp import stamp

from rubcosim.reference import System, simulate

REPO = Path(__file__).resolve().parents[1]
DEFAULT_OUT = REPO / "benchmarks" / "results" / "engines.json"
DEFAULT_MD = REPO / "benchmarks" / "results" / "engines.md"

REFERENCE_RTOL = 1e-12
# rtol scan, loosest first: 1e-6, 3.16e-7, 1e-7, ..., 1e-12 (half decades).
RTOL_SCAN = tuple(10.0 ** (-e / 2.0) for e in range(12, 25))
INTEGRATORS = ("fast", "accurate", "scipy_loop")
LABELS = {"fast": "`fast`", "accurate": "`accurate`", "scipy_loop": "scipy `solve_ivp` loop"}
MIN_TIMED_S = 0.3  # keep repeating quick runs until this much time has been measured
MAX_RUNS = 200


def check_reference(case: Case, system: System, t_eval: np.ndarray) -> tuple[Run, dict[str, Any]]:
    """The reference run and the checks that make the case fit for the scipy loop."""
    t_end = float(t_eval[-1])
    t0 = time.perf_counter()
    res = simulate(
        system, t_end, t_eval=t_eval, engine="accurate", rtol=REFERENCE_RTOL, max_events=MAX_EVENTS
    )
    wall = time.perf_counter() - t0
    if not res.ok:
        raise RuntimeError(f"{case.name}: reference run failed: {res.message}")
    period = system.forcing_period
    n_periods = int(round(t_end / period))
    impacts = res.events.t[res.events.of_kind("impact")]
    per_period = np.bincount(
        np.minimum((impacts / period).astype(int), n_periods - 1), minlength=n_periods
    )
    other_events = int(res.events.t.shape[0] - impacts.shape[0])
    info = {
        "rtol": REFERENCE_RTOL,
        "final_mode": res.final_mode,
        "impacts": int(impacts.shape[0]),
        "impacts_per_period_min": int(per_period.min()),
        "impacts_per_period_max": int(per_period.max()),
        "non_impact_events": other_events,
        "min_rebound_normal_speed_over_velocity_scale": _min_rebound(case, res, system),
        "wall_s": wall,
    }
    if res.final_mode != 0 or other_events or per_period.min() != per_period.max():
        raise RuntimeError(
            f"{case.name}: the reference does not keep a steady impacting motion: {info}"
        )
    pos = np.column_stack([res.output(name) for name in case.positions])
    return Run(pos, int(impacts.shape[0]), res.counters["rhs_evaluations"], wall), info


def _min_rebound(case: Case, res: Any, system: System) -> float:
    """Smallest normal rebound speed over the velocity scale: how far from chattering."""
    idx = res.events.of_kind("impact")
    if idx.shape[0] == 0:
        return math.nan
    st = res.events.state[idx]
    if "stator" in case.params:
        s = case.params["stator"]
        rx, ry = st[:, 0] - s["x_offset"], st[:, 1] - s["y_offset"]
        speed = -(st[:, 2] * rx + st[:, 3] * ry) / np.hypot(rx, ry)
    else:
        speed = np.abs(st[:, 1])
    return float(speed.min() / system.velocity_scale)


def choose_rtol(
    kind: str, case: Case, system: System, t_eval: np.ndarray, ref: Run, target: float
) -> tuple[float, list[dict[str, Any]]]:
    """Loosest rtol of the scan whose error and the next tighter one's are <= target."""
    scan: list[dict[str, Any]] = []
    run_once(kind, case, system, t_eval, RTOL_SCAN[0])  # warm-up (numba compilation)
    chosen = None
    for i, rtol in enumerate(RTOL_SCAN):
        run = run_once(kind, case, system, t_eval, rtol)
        err = max_error(run.positions, ref.positions)
        scan.append({"rtol": rtol, "error": err, "impacts": run.impacts, "wall_s": run.wall_s})
        ok = err <= target
        if ok and chosen is None:
            chosen = i
        elif not ok:
            chosen = None
        if chosen is not None and (i > chosen or i == len(RTOL_SCAN) - 1):
            return RTOL_SCAN[chosen], scan
    raise RuntimeError(f"{kind} on {case.name}: no rtol in the scan reaches error <= {target:g}")


def time_runs(
    kind: str, case: Case, system: System, t_eval: np.ndarray, rtol: float, repeats: int
) -> tuple[list[float], Run]:
    """Wall times after one warm-up run: at least ``repeats`` runs and ~MIN_TIMED_S of them."""
    last = run_once(kind, case, system, t_eval, rtol)
    walls: list[float] = []
    while len(walls) < repeats or (sum(walls) < MIN_TIMED_S and len(walls) < MAX_RUNS):
        last = run_once(kind, case, system, t_eval, rtol)
        walls.append(last.wall_s)
    return walls, last


def bench_case(
    case: Case, periods: int, repeats: int, target: float, rounds: int
) -> dict[str, Any]:
    start = time.perf_counter()
    state = settle(case)
    system = case.system(state)
    period = system.forcing_period
    t_eval = period * np.arange(periods + 1)
    ref, ref_info = check_reference(case, system, t_eval)
    out: dict[str, Any] = {
        "name": case.name,
        "description": case.description,
        "params": case.params,
        "initial_state": dict(zip(case.state_keys, map(float, state), strict=True)),
        "forcing_period_s": period,
        "periods": periods,
        "positions": list(case.positions),
        "state_scale": system.state_scale.tolist(),
        "reference": ref_info,
        "integrators": {},
    }
    for kind in INTEGRATORS:
        rtol, scan = choose_rtol(kind, case, system, t_eval, ref, target)
        walls, run = time_runs(kind, case, system, t_eval, rtol, repeats)
        median = statistics.median(walls)
        out["integrators"][kind] = {
            "rtol": rtol,
            "atol_relative_to_state_scale": rtol,
            "error": max_error(run.positions, ref.positions),
            "impacts": run.impacts,
            "rhs_evaluations_per_period": run.rhs_evaluations / periods,
            "runs": len(walls),
            "wall_median_s": median,
            "wall_min_s": min(walls),
            "wall_max_s": max(walls),
            "wall_per_period_s": median / periods,
            "scan": scan,
        }
        err = out["integrators"][kind]["error"]
        print(
            f"  {case.name:8s} {kind:10s} rtol {rtol:8.2e}  error {err:.2e}"
            f"  {median / periods * 1e6:10.1f} us/period  ({len(walls)} runs)",
            file=sys.stderr,
            flush=True,
        )
    ints = out["integrators"]
    fast = ints["fast"]["wall_median_s"]
    # the floor of `fast`: its right-hand-side calls per period at the cost of one call,
    # and its distance to it, in rounds that each take both (floor_rounds)
    fl = floor_rounds(case, system, state, t_eval, ints["fast"]["rtol"], rounds)
    out["floor_rounds"] = fl["rounds"]
    out["rhs_call_s"] = fl["rhs_call_s"]
    out["rhs_chained_call_s"] = fl["rhs_chained_call_s"]
    calls = ints["fast"]["rhs_evaluations_per_period"]
    out["fast_floor_per_period_s"] = calls * fl["rhs_call_s"]["median"]
    out["fast_over_floor"] = fl["fast_over_floor"]
    out["target_fast_over_floor"] = 2.0
    out["fast_over_chained_floor"] = fl["fast_over_chained_floor"]
    out["free_flight"] = free_flight(case, periods, ints["fast"]["rtol"], rounds)
    out["fast_call_s"] = call_cost(system, ints["fast"]["rtol"], repeats)
    out["speedup_fast_vs_scipy_loop"] = ints["scipy_loop"]["wall_median_s"] / fast
    out["speedup_fast_vs_accurate"] = ints["accurate"]["wall_median_s"] / fast
    out["target_fast_vs_scipy_loop"] = 100.0
    out["target_met"] = out["speedup_fast_vs_scipy_loop"] >= 100.0
    out["bench_wall_s"] = time.perf_counter() - start
    return out


# ---------------------------------------------------------------------------- output
def _fmt_time(s: float) -> str:
    if s >= 1e-3:
        return f"{s * 1e3:.3g} ms"
    return f"{s * 1e6:.3g} µs"


def markdown(report: dict[str, Any]) -> str:
    meta = report["meta"]
    lines = [
        "# Engine benchmark: wall time per forcing period at equal accuracy",
        "",
        f"Target error {meta['target_error']:g} (max stroboscopic position error vs "
        f"`accurate` at rtol {REFERENCE_RTOL:g}, normalised by the reference's max |position|), "
        f"{meta['periods']} forcing periods from a state on the attractor; median of "
        f">= {meta['repeats']} runs after a warm-up.  {meta['date']}, {meta['cpu_count']} CPUs, "
        f"Python {meta['python']}, numpy {meta['numpy']}, scipy {meta['scipy']}, "
        f"numba {meta['numba']}, commit {meta['git_commit'][:10]}.",
        "",
        "| case | integrator | rtol | error | impacts | rhs calls / period | wall time / period "
        "| time / `fast` time |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for case in report["cases"]:
        fast = case["integrators"]["fast"]["wall_median_s"]
        for kind in INTEGRATORS:
            r = case["integrators"][kind]
            lines.append(
                f"| {case['name']} | {LABELS[kind]} | {r['rtol']:.2g} | {r['error']:.2g} | "
                f"{r['impacts']} | {r['rhs_evaluations_per_period']:.0f} | "
                f"{_fmt_time(r['wall_per_period_s'])} | "
                f"{r['wall_median_s'] / fast:.3g}x |"
            )
    lines += ["", "| case | `fast` vs scipy loop | `fast` vs `accurate` | target (>= 100x) |"]
    lines += ["|---|---:|---:|---|"]
    for case in report["cases"]:
        met = "met" if case["target_met"] else "NOT met"
        lines.append(
            f"| {case['name']} | {case['speedup_fast_vs_scipy_loop']:.3g}x | "
            f"{case['speedup_fast_vs_accurate']:.3g}x | {met} |"
        )
    lines.append("")
    rounds = report["cases"][0]["floor_rounds"] if report["cases"] else 0
    lines += [
        "Distance of `fast` to its floor: its right-hand-side calls per period times the cost "
        "of one compiled call, in a loop of calls spread over one forcing period.  Taken in "
        f"{rounds} rounds, each one `fast` run and at once a loop of as many calls as it made: "
        "the figures are the medians over the rounds (min-max in brackets), the ratio that of "
        "the rounds' own ratios.  The target is judged on that floor.  Within a Runge-Kutta "
        "step each stage's state depends on the stages before it, so the calls cannot "
        "overlap as they do in that loop; the last two columns measure a call in a loop "
        "where each call waits for the one before (in the same rounds), and `fast`'s "
        "distance to that floor.  The last column is `fast`'s distance to its floor on the "
        "same model with the obstacle out of reach (settled, at the same rtol, in as many "
        "rounds): the step loop without an event, so the difference from the impacting "
        "case is what its events cost.",
        "",
        "| case | rhs call | floor / period | `fast` / period | `fast` / floor | target (<= 2x) "
        "| chained rhs call | `fast` / chained floor | `fast` / floor, free flight |",
        "|---|---:|---:|---:|---:|---|---:|---:|---:|",
    ]
    for case in report["cases"]:
        ratio = case["fast_over_floor"]["median"]
        lines.append(
            f"| {case['name']} | {_ns(case['rhs_call_s'])} | "
            f"{_fmt_time(case['fast_floor_per_period_s'])} | "
            f"{_fmt_time(case['integrators']['fast']['wall_per_period_s'])} | "
            f"{_ratio(case['fast_over_floor'])} | "
            f"{'met' if ratio <= case['target_fast_over_floor'] else 'NOT met'} | "
            f"{_ns(case['rhs_chained_call_s'])} | {_ratio(case['fast_over_chained_floor'])} | "
            f"{_ratio(case['free_flight']['fast_over_floor'])} |"
        )
    lines.append("")
    for case in report["cases"]:
        c = case["fast_call_s"]
        run = case["integrators"]["fast"]["wall_median_s"]
        lines.append(
            f"A `fast` `simulate` call of one step (1e-6 of a period) on the {case['name']} "
            f"takes {c['median'] * 1e6:.3g} µs ({c['min'] * 1e6:.3g}-{c['max'] * 1e6:.3g}): "
            f"what each run above pays besides its steps, {100 * c['median'] / run:.2g} % of "
            "its time."
        )
    lines.append("")
    for case in report["cases"]:
        lines.append(f"- **{case['name']}**: {case['description']}.")
    lines.append("")
    return "\n".join(lines)


def _ns(c: dict[str, float]) -> str:
    """A call's cost: median (min-max), ns."""
    return f"{c['median'] * 1e9:.1f} ns ({c['min'] * 1e9:.1f}-{c['max'] * 1e9:.1f})"


def _ratio(r: dict[str, float]) -> str:
    """A ratio over the rounds: median (min-max)."""
    return f"{r['median']:.3g}x ({r['min']:.3g}-{r['max']:.3g})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="JSON result file")
    ap.add_argument("--md", type=Path, default=DEFAULT_MD, help="Markdown table file")
    ap.add_argument("--periods", type=int, default=50, help="forcing periods per run")
    ap.add_argument("--repeats", type=int, default=5, help="minimum timed runs per integrator")
    ap.add_argument("--target", type=float, default=1e-8, help="error every integrator must reach")
    ap.add_argument(
        "--floor-rounds", type=int, default=31, help="rounds of the distance to the floor"
    )
    ap.add_argument(
        "--cases", nargs="+", choices=[c.name for c in CASES], default=[c.name for c in CASES]
    )
    args = ap.parse_args(argv)
    if args.periods < 1 or args.repeats < 1 or args.floor_rounds < 1:
        ap.error("--periods, --repeats and --floor-rounds must be >= 1")

    start = time.perf_counter()
    cases = [
        bench_case(c, args.periods, args.repeats, args.target, args.floor_rounds)
        for c in CASES
        if c.name in args.cases
    ]
    report = {
        "meta": stamp(
            periods=args.periods,
            repeats=args.repeats,
            floor_rounds=args.floor_rounds,
            target_error=args.target,
            reference=f"simulate(engine='accurate', rtol={REFERENCE_RTOL:g})",
            rtol_scan=list(RTOL_SCAN),
            rtol_rule="loosest rtol with error <= target whose next tighter rtol also passes",
            total_wall_s=None,
        ),
        "cases": cases,
    }
    report["meta"]["total_wall_s"] = time.perf_counter() - start
    table = markdown(report)
    for path, text in ((args.out, json.dumps(report, indent=2) + "\n"), (args.md, table)):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
