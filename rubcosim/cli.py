"""The ``rubcosim`` command."""

from __future__ import annotations

import argparse
import gc
import os
import shutil
import sys
from typing import Any

from rubcosim.components.parameters import ParameterError
from rubcosim.components.wiring import CouplingError
from rubcosim.orchestrator.cosim_result import CosimError
from rubcosim.orchestrator.settings import BACKENDS
from rubcosim.reference.simulate import ENGINES

from . import api, cli_control, cli_lyapunov, cli_ssp
from .analysis.errors import AnalysisError
from .analysis.sweep import DIRECTIONS
from .basinsettings import BASIN_METHODS
from .cli_options import add_set_option
from .scenario import ScenarioError
from .writing import check_output_dir, write_directory

SCENARIO_HELP = "a bundled scenario's name (see `rubcosim scenarios`) or a scenario TOML file"

EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 3


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
    _analysis_parsers(sub)
    cli_lyapunov.add_parser(sub, SCENARIO_HELP)
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


def _analysis_parsers(sub: Any) -> None:
    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument("scenario", help=SCENARIO_HELP)
        add_set_option(p, "a parameter or initial state")
        p.add_argument("--out", required=True, help="output directory")
        p.add_argument(
            "--rtol",
            type=float,
            default=None,
            help="the fast engine's relative tolerance for the maps",
        )
        p.add_argument(
            "--workers",
            type=int,
            default=None,
            help="local worker processes (default: the usable cores)",
        )
        p.add_argument(
            "--scheduler",
            default=None,
            metavar="ADDRESS",
            help="run the tasks on this Dask scheduler (e.g. tcp://host:8786)",
        )
        p.add_argument("--no-progress", action="store_true", help="no progress bar")

    sw = sub.add_parser("sweep", help="bifurcation diagram by continuation over a parameter")
    common(sw)
    sw.add_argument(
        "--param",
        required=True,
        metavar="UNIT.PARAM=START:STOP:COUNT",
        help="the swept parameter and its values",
    )
    sw.add_argument("--periods", type=int, default=100, help="stroboscopic points kept per value")
    sw.add_argument("--discard", type=int, default=200, help="transient periods per value")
    sw.add_argument(
        "--direction", choices=DIRECTIONS, default="up", help="sweep up, down, or both (hysteresis)"
    )
    sw.add_argument(
        "--chains",
        type=int,
        default=1,
        help="independent continuation chains per direction (parallel)",
    )
    sw.add_argument(
        "--section",
        choices=("strobe", "impact"),
        default="strobe",
        help="what bifurcation.png draws: the stroboscopic section (default) or the impact "
        "section (forcing phase of every impact)",
    )
    sw.add_argument(
        "--floquet",
        action="store_true",
        help="Floquet multipliers (stability, kind of bifurcation) of each periodic motion "
        "of period <= 8",
    )
    sw.add_argument(
        "--lyapunov",
        action="store_true",
        help="largest Lyapunov exponent (1/s) of each value's motion over --periods periods",
    )
    sw.add_argument(
        "--grazing",
        action="store_true",
        help="locate each grazing between sweep values (impacts start or stop) and fit the "
        "square-root law there",
    )
    sw.add_argument(
        "--plot-state",
        default=None,
        metavar="NAME",
        help="state drawn against the parameter (default: the first)",
    )
    bs = sub.add_parser("basins", help="basins of attraction by generalized cell mapping")
    common(bs)
    bs.add_argument(
        "--grid", metavar="NXxNV", help="cells in x and x' (default: the scenario's basins.grid)"
    )
    bs.add_argument("--samples", type=int, help="random points per cell (basins.samples)")
    bs.add_argument(
        "--region", metavar="X0:X1,V0:V1", help="the section's region in (x, x') (basins.region)"
    )
    bs.add_argument("--seed", type=int, help="seed of the sample points (basins.seed, else 0)")
    bs.add_argument(
        "--method",
        default=None,
        help=f"{' or '.join(BASIN_METHODS)}; gcm (default): generalized cell mapping on "
        "the one-period map; pursuit: every sample followed to a verified attractor, "
        "saddles by Newton (for maps close to the identity, e.g. "
        "scenarios/feng_yang_attractors.toml); slice (default with --slice): every "
        "sample followed in the full state space, any delay-free system; default: the "
        "scenario's basins.method",
    )
    bs.add_argument(
        "--slice",
        default=None,
        metavar="NAME1,NAME2",
        help="the two state components the grid spans (default: the first two); the "
        "others keep the scenario's initial values, e.g. oscillator.x2,oscillator.v2",
    )


def cmd_sweep(args: argparse.Namespace) -> int:
    from .analysis.outputs import checkpoint_dir, write_sweep
    from .analysis.sweep import parse_param

    scenario = api.load(args.scenario, args.set)
    param = parse_param(args.param)
    out = check_output_dir(args.out)
    names = scenario.system.state_names
    plot_state = 0
    if args.plot_state is not None:
        if args.plot_state not in names:
            raise ScenarioError(f"--plot-state {args.plot_state!r}: not one of {', '.join(names)}")
        plot_state = names.index(args.plot_state)
    ckpt = checkpoint_dir(out)
    result = api.sweep(
        scenario,
        param,
        periods=args.periods,
        discard=args.discard,
        direction=args.direction,
        rtol=args.rtol,
        floquet=args.floquet,
        lyapunov=args.lyapunov,
        grazing=args.grazing,
        chains=args.chains,
        workers=args.workers,
        scheduler=args.scheduler,
        checkpoint_dir=ckpt,
        progress=not args.no_progress,
    )
    drawn = "impact" if args.section == "impact" else plot_state
    write_directory(out, lambda tmp: write_sweep(result, tmp, scenario.name, drawn))
    shutil.rmtree(ckpt, ignore_errors=True)
    for g in result.grazings:
        print(
            f"grazing at {param.name} = {g['value']:.10g}: square-root law exponent "
            f"{g['sqrt_law']['exponent']:.3f} (expected 0.5)"
        )
    print(
        f"{scenario.name}: swept {param.name} over {param.count} values "
        f"({', '.join(result.points)}); failed values {result.failed} -> {out}"
    )
    return EXIT_RUN_FAILED if any(result.failed.values()) else 0


def _run_basins(args: argparse.Namespace, scenario: Any, opts: dict[str, Any], ckpt: Any) -> Any:
    return api.basins(
        scenario,
        opts["grid"],
        opts["samples"],
        opts["region"],
        seed=opts["seed"],
        rtol=args.rtol,
        workers=args.workers,
        scheduler=args.scheduler,
        checkpoint_dir=ckpt,
        progress=not args.no_progress,
        method=opts["method"],
        slice=opts["slice"],
    )


def cmd_basins(args: argparse.Namespace) -> int:
    from .analysis.cellmap import Grid
    from .analysis.outputs import checkpoint_dir, write_basins
    from .analysis.published import basins_summary
    from .analysis.slices import parse_slice
    from .figure_process import FigureProcess

    scenario = api.load(args.scenario, args.set)
    # the flags, else the scenario's [basins] table; bad input is refused before --out
    keys = ("grid", "samples", "region", "seed", "method", "slice")
    opts = {k: getattr(args, k) for k in keys}
    opts = {k: v if v is not None else scenario.basins.get(k) for k, v in opts.items()}
    for key in ("grid", "samples", "region"):
        if opts[key] is None:
            raise AnalysisError(
                f"--{key}: not given, and the scenario has no basins.{key} to default to"
            )
    Grid.parse(opts["grid"], opts["region"])
    if opts["slice"] is not None:
        parse_slice(scenario.system, opts["slice"])
    if opts["method"] not in (None, *BASIN_METHODS):
        raise AnalysisError(f"--method {opts['method']!r}: one of {', '.join(BASIN_METHODS)}")
    out = check_output_dir(args.out)
    ckpt = checkpoint_dir(out)
    # the figure's helper process: forked now, before the analysis starts its workers
    with FigureProcess() as figures:
        basins = _run_basins(args, scenario, opts, ckpt)
        write_directory(
            out, lambda tmp: write_basins(basins, tmp, scenario.name, basins.info, figures)
        )
    shutil.rmtree(ckpt, ignore_errors=True)
    c = basins.counts()
    labels = ", ".join(m["label"] for m in basins.motions)
    print(
        f"{scenario.name}: {basins.n_attractors} attractor(s) ({labels}); basin cells "
        f"{c['basins']}, boundary {c['boundary']}, escape {c['escape']}; "
        f"{basins.info['wall_time_s']:.1f} s -> {out}"
    )
    for line in basins_summary(basins, scenario.name):
        print(line)
    return 0


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
    "sweep": cmd_sweep,
    "basins": cmd_basins,
    "lyapunov": cli_lyapunov.cmd_lyapunov,
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
