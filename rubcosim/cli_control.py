"""``rubcosim control-study``: chaos control by delayed feedback, judged by success rates."""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path
from typing import Any

from . import api
from .cli_options import add_set_option


def _floats(text: str | None, what: str) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        from .analysis.errors import AnalysisError

        raise AnalysisError(f"{what} {text!r}: expected comma-separated numbers") from None


def add_parser(sub: Any, scenario_help: str) -> None:
    """The ``control-study`` sub-command's arguments."""
    p = sub.add_parser(
        "control-study",
        help="uncontrolled Lyapunov spectrum, target orbit, success of delayed feedback",
    )
    p.add_argument("scenario", help=scenario_help)
    add_set_option(p, "a parameter or initial state")
    p.add_argument(
        "--switch-on",
        required=True,
        metavar="A:B:N",
        help="N switch-on times spread over [A, B] (s)",
    )
    p.add_argument("--gains", help="feedback gains, comma-separated (default: the scenario's)")
    p.add_argument("--memory", help="ETDAS memories R, comma-separated (default: the scenario's)")
    p.add_argument("--periods", type=int, default=200, help="forcing periods after switch-on")
    p.add_argument(
        "--lyapunov-periods", type=int, default=500, help="periods of the uncontrolled spectrum"
    )
    p.add_argument("--transient", type=int, default=200, help="uncontrolled periods discarded")
    p.add_argument("--rtol", type=float, default=1e-10, help="the fast engine's tolerance")
    p.add_argument("--out", required=True, help="directory for report.json, runs.csv, figures")
    p.add_argument("--workers", type=int, default=None, help="local processes (default: cores)")
    p.add_argument("--scheduler", default=None, help="run the runs on this Dask scheduler")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _fmt(v: float) -> str:
    return f"{v:+.5g}" if math.isfinite(v) else str(v)


def write_outputs(study: Any, out: Path) -> list[Path]:
    """report.json, runs.csv and, with runs, success.png."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "report.json"]
    paths[0].write_text(json.dumps(study.report(), indent=2))
    if not study.runs:
        return paths
    runs = out / "runs.csv"
    with runs.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(study.runs[0].__dict__))
        writer.writeheader()
        writer.writerows(r.__dict__ for r in study.runs)
    paths.append(runs)
    from .plots import control_success_figure

    paths.append(control_success_figure(study, out / "success.png"))
    return paths


def cmd_control_study(args: argparse.Namespace) -> int:
    scenario = api.load(args.scenario, args.set)
    study = api.control_study(
        scenario,
        args.switch_on,
        gains=_floats(args.gains, "--gains"),
        memories=_floats(args.memory, "--memory"),
        periods=args.periods,
        lyapunov_periods=args.lyapunov_periods,
        transient=args.transient,
        rtol=args.rtol,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    T = study.period
    lyap = study.lyapunov
    print(f"{scenario.name}: uncontrolled, over {lyap.intervals} forcing periods (T = {T:.6g} s)")
    print("  Lyapunov exponents (1/s): " + ", ".join(_fmt(v) for v in lyap.exponents))
    if study.target is None:
        print(f"  no target orbit of period {study.delay_periods}: {study.target_message}")
    else:
        f = study.target
        mults = ", ".join(f"{abs(z):.4g}" for z in f.multipliers[:3])
        print(
            f"  target: period-{f.period} orbit, {f.impacts} impacts per {f.period} period(s), "
            f"|multipliers| {mults} ({'stable' if f.stable else 'unstable'}, {f.kind}); "
            f"{study.target_message}"
        )
    if study.runs:
        print(f"  {'gain':>12} {'R':>6} {'success':>8} {'mean periods':>13}")
        for (g, m), rate in sorted(study.success_rates().items()):
            caught = [
                r.periods_to_converge
                for r in study.runs
                if r.gain == g and r.memory == m and r.converged
            ]
            mean = f"{sum(caught) / len(caught):.1f}" if caught else "-"
            print(f"  {g:>12.6g} {m:>6.3g} {rate:>8.0%} {mean:>13}")
    for path in write_outputs(study, Path(args.out)):
        print(f"wrote {path}")
    return 0
