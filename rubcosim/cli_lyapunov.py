"""``rubcosim lyapunov``: the Lyapunov spectrum of a scenario's motion."""

from __future__ import annotations

import argparse
import math
from typing import Any

from . import api
from .cli_options import add_set_option


def add_parser(sub: Any, scenario_help: str) -> None:
    """The ``lyapunov`` sub-command's arguments."""
    ly = sub.add_parser(
        "lyapunov",
        help="Lyapunov spectrum from the variational equations (saltation at every event)",
    )
    ly.add_argument("scenario", help=scenario_help)
    add_set_option(ly, "a parameter or initial state")
    ly.add_argument("--periods", type=int, default=1000, help="forcing periods measured")
    ly.add_argument("--transient", type=int, default=200, help="forcing periods discarded first")
    ly.add_argument("--rtol", type=float, default=None, help="the fast engine's tolerance")
    ly.add_argument(
        "--uncontrolled",
        action="store_true",
        help="the scenario without its delayed-feedback controller",
    )


def _fmt(v: float) -> str:
    return f"{v:+.6g}" if math.isfinite(v) else str(v)


def cmd_lyapunov(args: argparse.Namespace) -> int:
    scenario = api.load(args.scenario, args.set)
    lyap = api.lyapunov(
        scenario,
        periods=args.periods,
        transient=args.transient,
        rtol=args.rtol,
        uncontrolled=args.uncontrolled,
    )
    T = lyap.interval
    print(
        f"{scenario.name}{' without its controller' if args.uncontrolled else ''}: "
        f"Lyapunov spectrum over {lyap.intervals} forcing periods "
        f"(T = {T:.6g} s) after {lyap.transient}; {lyap.impacts / lyap.intervals:.4g} "
        "impacts per period"
    )
    print(f"{'':4}{'per unit time (1/s)':>22}{'per period':>16}{'first half (1/s)':>20}")
    for i, (lam, half) in enumerate(zip(lyap.exponents, lyap.half, strict=True)):
        print(f"{i + 1:<4}{_fmt(lam):>22}{_fmt(lam * T):>16}{_fmt(half):>20}")
    total = float(sum(lyap.exponents))
    print(f"{'sum':<4}{_fmt(total):>22}{_fmt(total * T):>16}")
    print(
        f"Liouville (mean tr J + ln|det S| of the events per unit time): {_fmt(lyap.liouville)} "
        f"1/s = {_fmt(lyap.trace)} (tr J) {_fmt(lyap.jumps)} (events)"
    )
    return 0
