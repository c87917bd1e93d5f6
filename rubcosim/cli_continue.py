"""``rubcosim continue``: pseudo-arclength continuation of a periodic orbit."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from . import api, api_continuation
from .cli_options import EXIT_RUN_FAILED, add_set_option, plot_state_index
from .scenario import ScenarioError
from .writing import check_output_dir, write_directory


def add_parser(sub: Any, scenario_help: str) -> None:
    """The ``continue`` sub-command's arguments."""
    co = sub.add_parser(
        "continue",
        help="continue a periodic orbit in a parameter: stable and unstable orbits, "
        "Floquet multipliers, folds, flips and Neimark-Sacker points",
    )
    co.add_argument("scenario", help=scenario_help)
    add_set_option(co, "a parameter or initial state")
    co.add_argument("--param", required=True, metavar="UNIT.PARAM", help="the parameter")
    co.add_argument(
        "--from",
        dest="from_value",
        type=float,
        default=None,
        help="where the branch starts (default: the parameter's value in the scenario)",
    )
    co.add_argument("--to", dest="to_value", type=float, required=True, help="toward this value")
    co.add_argument("--period", type=int, default=1, help="the orbit's period n in forcing periods")
    co.add_argument(
        "--start",
        dest="start_state",
        default=None,
        metavar="Y1,Y2,...",
        help="the orbit's state at forcing phase 0, near enough for Newton (default: where "
        "the initial state settles after --settle periods)",
    )
    co.add_argument(
        "--start-from",
        default=None,
        metavar="DIR",
        help="start from a fixed point (by default the first saddle) of a `rubcosim basins` "
        "output directory, e.g. a saddle on a basin boundary",
    )
    co.add_argument(
        "--fixed-point",
        type=int,
        default=None,
        metavar="K",
        help="with --start-from: the K-th of its report's fixed_points (0-based)",
    )
    co.add_argument("--settle", type=int, default=300, help="periods settled before Newton")
    co.add_argument("--out", required=True, help="output directory")
    co.add_argument("--rtol", type=float, default=None, help="the map's tolerance (1e-12)")
    co.add_argument(
        "--step", type=float, default=0.02, help="first arclength step, fraction of the range"
    )
    co.add_argument("--max-step", type=float, default=0.05, help="largest arclength step, fraction")
    co.add_argument("--max-points", type=int, default=500, help="points at most per branch")
    co.add_argument(
        "--doublings",
        type=int,
        default=0,
        metavar="K",
        help="switch at the first flip onto the period-doubled branch, K times: the "
        "cascade's flips and their Feigenbaum ratios",
    )
    co.add_argument(
        "--plot-state", default=None, metavar="NAME", help="state drawn (default: the first)"
    )
    co.add_argument(
        "--over-sweep",
        default=None,
        metavar="DIR",
        help="a `rubcosim sweep` output of the same parameter, drawn beneath the branch",
    )
    co.add_argument(
        "--curve",
        choices=("fold", "flip"),
        default=None,
        help="then follow the branch's first such point in two parameters (--param2)",
    )
    co.add_argument("--param2", default=None, metavar="UNIT.PARAM", help="the second parameter")
    co.add_argument(
        "--from2", type=float, default=None, help="its start (default: the scenario's value)"
    )
    co.add_argument("--to2", type=float, default=None, help="the curve runs toward this value")
    co.add_argument("--no-progress", action="store_true", help="no progress bar")


def _start(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise ScenarioError(f"--start {text!r}: expected numbers separated by commas") from None


def _describe(sp: Any, param: str) -> str:
    if sp.kind == "grazing":
        law = sp.details.get("sqrt_law", {})
        fit = f", square-root law exponent {law['exponent']:.3f}" if "exponent" in law else ""
        where = "" if sp.details.get("located") else " (bracketed, not located)"
        return f"grazing at {param} = {sp.param:.10g}{where}{fit}"
    lam = sp.critical
    return (
        f"{sp.kind} at {param} = {sp.param:.10g} (critical multiplier "
        f"{lam.real:+.6f}{lam.imag:+.6f}j, residual {sp.residual:.1e})"
    )


def _fixed_point(folder: str, k: int | None) -> list[float]:
    """The state of fixed point ``k`` (default: the first saddle) of a basins report."""
    path = Path(folder) / "report.json"
    try:
        points = json.loads(path.read_text())["fixed_points"]
    except (OSError, ValueError, KeyError):
        raise ScenarioError(
            f"--start-from {folder}: holds no basins report with fixed points"
        ) from None
    if k is None:
        k = next((i for i, p in enumerate(points) if p.get("saddle")), None)
        if k is None:
            raise ScenarioError(f"--start-from {folder}: its report has no saddle")
    if not (0 <= k < len(points)):
        raise ScenarioError(f"--fixed-point {k}: the report has {len(points)} fixed points")
    return [float(v) for v in points[k]["state"]]


def cmd_continue(args: argparse.Namespace) -> int:
    from .analysis.continuation_outputs import branches_of, write_continuation
    from .analysis.continue_scenario import settings_of

    scenario = api.load(args.scenario, args.set)
    out = check_output_dir(args.out)
    if args.start_from is not None and args.start_state is not None:
        raise ScenarioError("--start and --start-from: give one of them")
    if args.fixed_point is not None and args.start_from is None:
        raise ScenarioError("--fixed-point: goes with --start-from")
    if args.curve is not None and (args.param2 is None or args.to2 is None):
        raise ScenarioError("--curve: give --param2 and --to2 (and --from2 if not the scenario's)")
    plot_state = plot_state_index(scenario.system.state_names, args.plot_state)
    sweep = None
    if args.over_sweep is not None:
        sweep = Path(args.over_sweep) / "sweep.npz"
        if not sweep.is_file():
            raise ScenarioError(f"--over-sweep {args.over_sweep}: holds no sweep.npz")
    branch = api_continuation.continuation(
        scenario,
        args.param,
        args.from_value,
        args.to_value,
        period=args.period,
        y0=_fixed_point(args.start_from, args.fixed_point)
        if args.start_from is not None
        else _start(args.start_state),
        settle=args.settle,
        rtol=args.rtol,
        step=args.step,
        max_step=args.max_step,
        max_points=args.max_points,
        doublings=args.doublings,
        progress=not args.no_progress,
    )
    curve = None
    if args.curve is not None:
        curve = api_continuation.bifurcation_curve(
            branch, args.curve, args.param2, args.to2, start2=args.from2,
            max_points=args.max_points,
        )  # fmt: skip
    settings = settings_of(
        branch, param=args.param, start=args.from_value, stop=args.to_value, rtol=args.rtol,
        step=args.step, max_step=args.max_step, max_points=args.max_points,
    )  # fmt: skip
    write_directory(
        out, lambda tmp: write_continuation(branch, tmp, settings, plot_state, sweep, curve)
    )
    for b in branches_of(branch):
        for sp in b.special:
            print(f"period {b.period}: {_describe(sp, branch.param)}")
        print(
            f"period {b.period}: {len(b.points)} points ({int(b.stable.sum())} stable); "
            f"stopped: {b.stop_reason}"
        )
    if branch.cascade is not None and branch.cascade.ratios.size:
        ratios = ", ".join(f"{r:.4g}" for r in branch.cascade.ratios)
        print(f"period-doubling ratios {ratios} (Feigenbaum: 4.669)")
    if curve is not None:
        print(
            f"{curve.kind} curve: {len(curve.points)} points, {curve.param2} from "
            f"{curve.params2[0]:.6g} to {curve.params2[-1]:.6g}; stopped: {curve.stop_reason}"
        )
    print(f"{scenario.name}: continued in {branch.param} -> {out}")
    return 0 if branch.points else EXIT_RUN_FAILED
