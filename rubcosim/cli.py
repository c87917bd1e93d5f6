"""The ``rubcosim`` command."""

from __future__ import annotations

import argparse
import sys

from rubcosim.components.parameters import ParameterError
from rubcosim.orchestrator.connections import CouplingError
from rubcosim.orchestrator.master import CosimError
from rubcosim.orchestrator.settings import BACKENDS
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
        "--backend",
        choices=BACKENDS,
        help="co-simulate the units with the orchestrator instead (direct: in-process units, "
        "fmu: the FMUs through fmpy); settings from the scenario's [cosim] table",
    )
    run.add_argument(
        "--out",
        required=True,
        help="output directory (replaced only when the new result is complete)",
    )
    check = sub.add_parser(
        "check", help="co-simulate a scenario and compare it with the monolithic reference"
    )
    check.add_argument("scenario", help="scenario TOML file")
    check.add_argument(
        "--backend", choices=BACKENDS, help="units in-process or as FMUs (default: [cosim])"
    )
    check.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="UNIT.PARAM=VALUE",
        help="override a parameter or a sim./cosim. setting (repeatable)",
    )
    check.add_argument("--out", required=True, help="directory for report.json and comparison.png")
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


def cmd_check(args: argparse.Namespace) -> int:
    import json
    from dataclasses import replace

    from rubcosim.orchestrator.check import compare, comparison_plot

    from .runner import check_output_dir, write_directory

    scenario = load_scenario(args.scenario, args.set)
    check_output_dir(args.out)
    settings = (
        scenario.cosim if args.backend is None else replace(scenario.cosim, backend=args.backend)
    )
    report, ref, co, rows = compare(scenario, settings)

    def fill(tmp):
        (tmp / "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        comparison_plot(scenario, ref, co, rows, tmp / "comparison.png")

    out = write_directory(args.out, fill)
    wall = report["wall_time_s"]
    print(
        f"{scenario.name}: co-simulation ({settings.backend}) vs reference: worst relative "
        f"error {report['worst_rel_error']:.3g}, impacts {report['impacts']['cosim']} vs "
        f"{report['impacts']['reference']}, {wall['cosim']:.3f} s vs {wall['reference']:.3f} s, "
        f"{co.counters.get('steps', 0)} steps ({co.counters.get('rejected', 0)} rejected) -> {out}"
    )
    if not co.ok:
        print(f"rubcosim: co-simulation failed: {co.message}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .runner import check_output_dir, run_cosim_scenario, run_scenario, write_results

    scenario = load_scenario(args.scenario, args.set)
    check_output_dir(args.out)
    if args.backend is not None:
        if args.engine is not None:
            raise ScenarioError("--engine and --backend exclude each other")
        crun = run_cosim_scenario(scenario, args.backend)
        out = write_results(crun, args.out)
        r = crun.result
        c = r.counters
        print(
            f"{scenario.name}: {r.engine}, t = {scenario.sim['t_start']:g}..{r.t_reached:g} s, "
            f"{c.get('events', 0)} events ({c.get('events_impact', 0)} impacts), "
            f"{c.get('accepted', 0)} steps, {c.get('rejected', 0)} rejected, "
            f"{c.get('snapshots', 0)} snapshots, {r.wall_time_s:.3f} s -> {out}"
        )
        if not r.ok:
            print(f"rubcosim: co-simulation failed: {r.message}", file=sys.stderr)
            return EXIT_RUN_FAILED
        return 0
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
        if args.command == "check":
            return cmd_check(args)
        if args.command == "build-fmus":
            return cmd_build_fmus(args)
    except (ScenarioError, ParameterError, CouplingError) as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except CosimError as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


if __name__ == "__main__":
    sys.exit(main())
