"""The ``rubcosim`` command."""

from __future__ import annotations

import argparse
import gc
import os
import sys

from rubcosim.components.parameters import ParameterError
from rubcosim.components.wiring import CouplingError
from rubcosim.orchestrator.cosim_result import CosimError
from rubcosim.orchestrator.settings import BACKENDS
from rubcosim.reference.simulate import ENGINES

from . import api, cli_continue, cli_control, cli_lyapunov, cli_maps, cli_ssp
from .analysis.errors import AnalysisError
from .chaos_check import summary
from .cli_options import EXIT_BAD_INPUT, EXIT_RUN_FAILED, add_set_option
from .scenario import ScenarioError
from .writing import check_output_dir

SCENARIO_HELP = "a bundled scenario's name (see `rubcosim scenarios`) or a scenario TOML file"


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="rubcosim", description="Nonsmooth rotor/stator rub-impact simulation."
    )
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scenario with the monolithic reference")
    run.add_argument("scenario", help=SCENARIO_HELP)
    add_set_option(run, "a parameter, initial state or sim setting")
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
    check.add_argument("scenario", help=SCENARIO_HELP)
    check.add_argument(
        "--backend", choices=BACKENDS, help="units in-process or as FMUs (default: [cosim])"
    )
    add_set_option(check, "a parameter or a sim./cosim. setting")
    check.add_argument("--out", required=True, help="directory for report.json and comparison.png")
    for parser in (run, check):
        parser.add_argument(
            "--no-progress",
            action="store_true",
            help="no progress bar (shown on a terminal for runs of more than 2 s)",
        )
        parser.add_argument(
            "--no-plots",
            action="store_true",
            help="write the results and report without plots (matplotlib is not loaded)",
        )
    cli_maps.add_parsers(sub, SCENARIO_HELP)
    cli_lyapunov.add_parser(sub, SCENARIO_HELP)
    cli_continue.add_parser(sub, SCENARIO_HELP)
    cli_control.add_parser(sub, SCENARIO_HELP)
    cli_ssp.add_parser(sub, SCENARIO_HELP)
    sub.add_parser("scenarios", help="list the bundled scenarios with their descriptions")
    warm = sub.add_parser(
        "warm-up",
        help="compile the numba kernels into the cache once (make run and make test run it)",
    )
    warm.add_argument("--workers", type=int, default=2, help="processes (default 2)")
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
    scenario = api.load(args.scenario, args.set)
    check_output_dir(args.out)
    checked = api.check(scenario, args.backend, progress=not args.no_progress)
    out = checked.write(args.out, plots=not args.no_plots)
    report, co = checked.report, checked.cosim
    wall = report["wall_time_s"]
    print(
        f"{scenario.name}: co-simulation ({co.settings.backend}, {co.master} master) vs "
        f"reference: worst relative "
        f"error {report['worst_rel_error']:.3g}, impacts {report['impacts']['cosim']} vs "
        f"{report['impacts']['reference']}, {wall['cosim']:.3f} s vs {wall['reference']:.3f} s, "
        f"{co.counters.get('steps', 0)} steps ({co.counters.get('rejected', 0)} rejected) -> {out}"
    )
    chaos = summary(report["chaos"])
    if chaos is not None:
        print(f"rubcosim: {chaos}")
    if not checked.ok:
        print(f"rubcosim: co-simulation failed: {co.message}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    scenario = api.load(args.scenario, args.set)
    check_output_dir(args.out)
    if args.backend is not None and args.engine is not None:
        raise ScenarioError("--engine and --backend exclude each other")
    if args.backend is not None:
        res = api.cosimulate(scenario, args.backend, progress=not args.no_progress)
        c = res.counters
        what = (
            f"{c.get('events', 0)} events ({c.get('events_impact', 0)} impacts), "
            f"{c.get('accepted', 0)} steps, {c.get('rejected', 0)} rejected, "
            f"{c.get('snapshots', 0)} snapshots"
        )
        engine, failure = f"{res.engine} ({res.run.result.master} master)", "co-simulation"
    else:
        res = api.simulate(scenario, args.engine, progress=not args.no_progress)
        c = res.counters
        what = f"{c['events']} events ({c['impacts']} impacts)"
        engine, failure = f"{res.engine} engine", "simulation"
    out = res.write(args.out, plots=not args.no_plots)
    print(
        f"{scenario.name}: {engine}, t = {scenario.sim['t_start']:g}..{res.t_reached:g} s, "
        f"{what}, {res.wall_time_s:.3f} s -> {out}"
    )
    if not res.ok:
        print(f"rubcosim: {failure} failed: {res.message}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


def cmd_scenarios(args: argparse.Namespace) -> int:
    for name, description in api.scenarios().items():
        print(f"{name:32s} {description}")
    return 0


def cmd_warm_up(args: argparse.Namespace) -> int:
    from .warmup import warm_up

    for what, seconds in warm_up(args.workers):
        print(f"compiled {what} in {seconds:.1f} s")
    return 0


COMMANDS = {
    "run": cmd_run,
    "check": cmd_check,
    "build-fmus": cmd_build_fmus,
    "sweep": cli_maps.cmd_sweep,
    "basins": cli_maps.cmd_basins,
    "lyapunov": cli_lyapunov.cmd_lyapunov,
    "continue": cli_continue.cmd_continue,
    "control-study": cli_control.cmd_control_study,
    "export-ssp": cli_ssp.cmd_export_ssp,
    "scenarios": cmd_scenarios,
    "warm-up": cmd_warm_up,
}


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except (ScenarioError, ParameterError, CouplingError, AnalysisError) as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except CosimError as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_RUN_FAILED


def console_main() -> int:
    """The ``rubcosim`` executable: :func:`main` with the cyclic garbage collector
    kept off numba's objects.

    Loading a cached engine brings in numba's typing and lowering registries and
    LLVM's objects: a few hundred thousand long-lived objects that every full
    collection, and the interpreter's collections at exit, would traverse again
    (a quarter of a second of a small run). Freezing them after the imports and
    after the command moves them out of the collector's sight; reference counting
    still frees objects, and exit still runs atexit handlers, joins threads and
    closes files. Callers in-process keep using :func:`main`, which freezes nothing.
    """
    gc.freeze()
    try:
        code = main()
    except BrokenPipeError:
        # the reader went away (``rubcosim basins ... | head -1``): stop quietly, and keep
        # Python from reporting the failed flush of stdout at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(console_main())
