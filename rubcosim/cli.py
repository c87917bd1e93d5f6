"""The ``rubcosim`` command."""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from typing import Any

from rubcosim.components.parameters import ParameterError
from rubcosim.orchestrator.connections import CouplingError
from rubcosim.orchestrator.master import CosimError
from rubcosim.orchestrator.settings import BACKENDS
from rubcosim.reference.simulate import ENGINES

from .analysis.errors import AnalysisError
from .analysis.sweep import DIRECTIONS
from .scenario import ScenarioError, load_scenario

CELL_MAP_RTOL = 1e-7  # cells are far coarser than this: the maps need no more

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
    _analysis_parsers(sub)
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
        p.add_argument("scenario", help="scenario TOML file")
        p.add_argument(
            "--set",
            action="append",
            default=[],
            metavar="UNIT.PARAM=VALUE",
            help="override a parameter or initial state (repeatable)",
        )
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
    bs.add_argument("--grid", required=True, metavar="NXxNV", help="cells in x and x'")
    bs.add_argument("--samples", type=int, required=True, help="random points per cell")
    bs.add_argument(
        "--region", required=True, metavar="X0:X1,V0:V1", help="the section's region in (x, x')"
    )
    bs.add_argument("--seed", type=int, default=0, help="seed of the sample points")


def _parse_grid(text: str) -> tuple[int, int]:
    try:
        nx, nv = (int(s) for s in text.lower().split("x"))
    except ValueError:
        raise ScenarioError(f"--grid {text!r}: expected NXxNV, e.g. 200x200") from None
    if nx < 1 or nv < 1:
        raise ScenarioError(f"--grid {text!r}: cell counts must be >= 1")
    return nx, nv


def _parse_region(text: str) -> tuple[float, float, float, float]:
    try:
        xs, vs = text.split(",")
        x0, x1 = (float(s) for s in xs.split(":"))
        v0, v1 = (float(s) for s in vs.split(":"))
    except ValueError:
        raise ScenarioError(f"--region {text!r}: expected X0:X1,V0:V1, e.g. -3:1,-6:6") from None
    return x0, x1, v0, v1


def _map_rtol(args: argparse.Namespace, default: float) -> float:
    rtol = default if args.rtol is None else args.rtol
    if not 1e-14 <= rtol < 1.0:
        raise ScenarioError(f"--rtol {rtol!r}: must be in [1e-14, 1)")
    return rtol


def cmd_sweep(args: argparse.Namespace) -> int:
    from .analysis.maps import DEFAULT_RTOL
    from .analysis.outputs import checkpoint_dir, write_sweep
    from .analysis.sweep import parse_param, sweep
    from .runner import check_output_dir, write_directory

    scenario = load_scenario(args.scenario, args.set)
    param = parse_param(args.param)
    out = check_output_dir(args.out)
    names = scenario.system.state_names
    plot_state = 0
    if args.plot_state is not None:
        if args.plot_state not in names:
            raise ScenarioError(f"--plot-state {args.plot_state!r}: not one of {', '.join(names)}")
        plot_state = names.index(args.plot_state)
    ckpt = checkpoint_dir(out)
    result = sweep(
        scenario,
        param,
        overrides=args.set,
        periods=args.periods,
        discard=args.discard,
        direction=args.direction,
        rtol=_map_rtol(args, DEFAULT_RTOL),
        workers=args.workers,
        scheduler=args.scheduler,
        checkpoint_dir=ckpt,
        chains=args.chains,
        progress=not args.no_progress,
    )
    multipliers = {}
    if args.floquet:
        from .analysis.floquet import floquet_along
        from .analysis.sweep import sweep_systems

        systems = sweep_systems(scenario.source, args.set, param, result.values)
        for d in result.points:
            periods = [c.get("period", 0) for c in result.classify(d)]
            multipliers[d] = floquet_along(systems, result.points[d], result.modes[d], periods)
    grazings = []
    if args.grazing:
        from .analysis.grazing import brackets, grazing

        first = next(iter(result.points))
        for lo, hi in brackets(result.values, result.impacts[first], result.status[first])[:5]:
            lo, hi = min(lo, hi), max(lo, hi)
            grazings.append(grazing(scenario.source, args.set, param.name, lo, hi).as_dict())
    drawn = "impact" if args.section == "impact" else plot_state
    write_directory(
        out, lambda tmp: write_sweep(result, tmp, scenario.name, drawn, grazings, multipliers)
    )
    shutil.rmtree(ckpt, ignore_errors=True)
    failed = {d: int((s != 0).sum()) for d, s in result.status.items()}
    for g in grazings:
        print(
            f"grazing at {param.name} = {g['value']:.10g}: square-root law exponent "
            f"{g['sqrt_law']['exponent']:.3f} (expected 0.5)"
        )
    print(
        f"{scenario.name}: swept {param.name} over {param.count} values "
        f"({', '.join(result.points)}); failed values {failed} -> {out}"
    )
    return EXIT_RUN_FAILED if any(failed.values()) else 0


def cmd_basins(args: argparse.Namespace) -> int:
    from .analysis.cellmap import Grid, cell_mapping
    from .analysis.maps import StroboscopicMap
    from .analysis.outputs import checkpoint_dir, write_basins
    from .runner import check_output_dir, write_directory

    scenario = load_scenario(args.scenario, args.set)
    nx, nv = _parse_grid(args.grid)
    grid = Grid(nx, nv, *_parse_region(args.region))
    out = check_output_dir(args.out)
    smap = StroboscopicMap(scenario.system, _map_rtol(args, CELL_MAP_RTOL))
    ckpt = checkpoint_dir(out)
    t0 = time.perf_counter()
    basins = cell_mapping(
        smap,
        grid,
        args.samples,
        args.seed,
        args.workers,
        args.scheduler,
        ckpt,
        progress=not args.no_progress,
    )
    wall = time.perf_counter() - t0
    info = {
        "parameters": scenario.parameters,
        "state_names": scenario.system.state_names,
        "rtol": smap.rtol,
        "wall_time_s": wall,
    }
    write_directory(out, lambda tmp: write_basins(basins, tmp, scenario.name, info))
    shutil.rmtree(ckpt, ignore_errors=True)
    c = basins.counts()
    labels = ", ".join(m["label"] for m in basins.motions)
    print(
        f"{scenario.name}: {basins.n_attractors} attractor(s) ({labels}); basin cells "
        f"{c['basins']}, boundary {c['boundary']}, escape {c['escape']}; {wall:.1f} s -> {out}"
    )
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
        if args.command == "sweep":
            return cmd_sweep(args)
        if args.command == "basins":
            return cmd_basins(args)
    except (ScenarioError, ParameterError, CouplingError, AnalysisError) as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except CosimError as exc:
        print(f"rubcosim: error: {exc}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return 0


if __name__ == "__main__":
    sys.exit(main())
