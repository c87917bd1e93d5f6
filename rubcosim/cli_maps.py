"""``rubcosim sweep`` and ``rubcosim basins``: the stroboscopic maps' studies."""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from typing import Any

from . import api
from .analysis.errors import AnalysisError
from .analysis.sweep import DIRECTIONS
from .basinsettings import BASIN_METHODS
from .cli_options import EXIT_RUN_FAILED, add_set_option, plot_state_index
from .writing import check_output_dir, write_directory


def add_parsers(sub: Any, scenario_help: str) -> None:
    """The ``sweep`` and ``basins`` sub-commands' arguments."""

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument("scenario", help=scenario_help)
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
    bs = sub.add_parser(
        "basins", help="basins of attraction, their attractors and saddles on the section"
    )
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
        help=f"{' or '.join(BASIN_METHODS)}; pursuit (default): every sample followed to a "
        "verified attractor, saddles by Newton; gcm: generalized cell mapping on the "
        "one-period map (faster; it misses attractors where the map is close to the "
        "identity, e.g. scenarios/feng_yang_attractors.toml, and its check then says so); "
        "slice (default with --slice): every sample followed in the full state space, "
        "any delay-free system; default: the scenario's basins.method",
    )
    bs.add_argument(
        "--continue",
        dest="continue_range",
        default=None,
        metavar="UNIT.PARAM=START:STOP:COUNT",
        help="basin fractions continued over a parameter: the basins at every value, the "
        "attractors matched from one value to the next, where they are born, die or merge",
    )
    bs.add_argument(
        "--check",
        type=int,
        default=None,
        metavar="N",
        help="samples whose fate is checked by direct simulation (default 100; 0: none)",
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
    plot_state = plot_state_index(scenario.system.state_names, args.plot_state)
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
        check=args.check,
    )


def cmd_basins(args: argparse.Namespace) -> int:
    from .analysis.cellmap import Grid
    from .analysis.fate_check import verdict
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
    if args.continue_range is not None:
        return _continue_basins(args, scenario, opts, out, ckpt)
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
    print(_metrics_line(json.loads((out / "report.json").read_text())["metrics"]))
    check = basins.info.get("fate_check")
    if check is not None:
        trusted = check["agree"] == check["checked"]
        print(
            f"rubcosim: {'' if trusted else 'warning: '}{verdict(check)}",
            file=None if trusted else sys.stderr,
        )
    return 0


def _metrics_line(m: dict[str, Any]) -> str:
    """One line of the basin metrics report.json holds (:mod:`.analysis.basin_metrics`)."""
    if "error" in m:
        return f"basin metrics: {m['error']}"
    e, w, b = m["basin_entropy"], m["wada"], m["boundary"]
    if "error" in e:
        return f"basin metrics: {e['error']}"
    fractal = "fractal by the ln 2 criterion" if e["ln2_criterion_fractal"] else "ln 2 silent"
    alpha = b.get("uncertainty_exponent")
    dim = f"boundary dimension {b['dimension']:.3f}, uncertainty exponent {alpha:.3f}" if (
        alpha is not None) else "boundary dimension not fitted"  # fmt: skip
    wada = "Wada" if w.get("wada") else "not Wada"
    return f"basin entropy Sb {e['Sb']:.4f}, Sbb {e['Sbb']:.4f} ({fractal}); {dim}; {wada}"


def _continue_basins(args: argparse.Namespace, scenario: Any, opts: dict[str, Any], out: Any,
                     ckpt: Any) -> int:  # fmt: skip
    """``rubcosim basins --continue``: :func:`rubcosim.api_continuation.basin_continuation`."""
    from . import api_continuation
    from .analysis.basin_continuation import write_basin_continuation
    from .analysis.sweep import parse_param

    param = parse_param(args.continue_range)
    result = api_continuation.basin_continuation(
        scenario, param.name, param.values, opts["grid"], opts["samples"], opts["region"],
        method=opts["method"], seed=opts["seed"], rtol=args.rtol, check=args.check,
        workers=args.workers, scheduler=args.scheduler, checkpoint_dir=ckpt,
    )  # fmt: skip
    write_directory(out, lambda tmp: write_basin_continuation(result, tmp, scenario.name))
    shutil.rmtree(ckpt, ignore_errors=True)
    for e in result.events:
        if e["event"] != "present":
            into = f" into A{e['into']}" if "into" in e else ""
            print(f"{param.name} = {e['value']:.6g}: A{e['attractor']} {e['event']}{into}")
    rep = result.report()
    print(
        f"{scenario.name}: basins at {param.count} values of {param.name}, "
        f"{result.n_ids} attractor(s) in all; {rep['fates_agreeing']} of "
        f"{rep['fates_checked']} sampled fates confirmed by direct simulation -> {out}"
    )
    doubtful = [
        f"{v['value']:.6g} ({v['fate_check']['agree']}/{v['fate_check']['checked']})"
        for v in rep["per_value"]
        if v["fate_check"] and v["fate_check"]["agree"] < v["fate_check"]["checked"]
    ]
    if doubtful:
        print(
            f"rubcosim: warning: at {len(doubtful)} value(s) direct simulation sends some "
            f"sampled fates elsewhere: {', '.join(doubtful)}; a finer grid or more samples "
            "per cell (report.json: per_value)",
            file=sys.stderr,
        )
    return 0
