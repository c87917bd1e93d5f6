"""The ``rubcosim`` command."""

from __future__ import annotations

import argparse
import sys

from rubcosim.components.parameters import ParameterError
from rubcosim.reference.simulate import ENGINES

from .scenario import ScenarioError, load_scenario

EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 3


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="rubcosim", description="Nonsmooth rotor/stator rub-impact simulation."
    )
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scenario with the monolithic reference")
    run.add_argument("scenario", help="scenario TOML file")
    run.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="UNIT.PARAM=VALUE",
        help="override a parameter, initial state or sim setting (repeatable)",
    )
    run.add_argument(
        "--engine", choices=sorted(ENGINES), help="integrator (default: the scenario's sim.engine)"
    )
    run.add_argument(
        "--out",
        required=True,
        help="output directory (replaced only when the new result is complete)",
    )
    build = sub.add_parser("build-fmus", help="build every unit as an FMI 2.0 co-simulation FMU")
    build.add_argument(
        "--out", default="build/fmus", help="directory for the .fmu files (default: build/fmus)"
    )
    build.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="MODEL_IDENTIFIER",
        help="build only this FMU, e.g. RubcosimJeffcottRotor (repeatable)",
    )
    return ap


def cmd_build_fmus(args: argparse.Namespace) -> int:
    from rubcosim.fmus.build import BuildError, BuildRequestError, build_fmus

    try:
        built = build_fmus(args.out, only=args.only or None)
    except BuildError as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT if isinstance(exc, BuildRequestError) else EXIT_RUN_FAILED
    for path in built:
        print(path)
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .runner import check_output_dir, run_scenario, write_results

    scenario = load_scenario(args.scenario, args.set)
    check_output_dir(args.out)
    run = run_scenario(scenario, engine=args.engine)
    out = write_results(run, args.out)
    r = run.result
    print(
        f"{scenario.name}: {r.engine} engine, t = {scenario.sim['t_start']:g}..{r.t_reached:g} s, "
        f"{r.counters['events']} events ({r.counters['impacts']} impacts), "
        f"{r.wall_time_s:.3f} s -> {out}"
    )
    if not r.ok:
        print(f"rubcosim: simulation failed: {r.message}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "run":
            return cmd_run(args)
        if args.command == "build-fmus":
            return cmd_build_fmus(args)
    except (ScenarioError, ParameterError) as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return 0


if __name__ == "__main__":
    sys.exit(main())
