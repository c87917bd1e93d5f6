"""``rubcosim export-ssp``: a scenario as an SSP 1.0 package for other FMI tools."""

from __future__ import annotations

import argparse
from typing import Any

from . import api
from .cli_options import add_set_option


def add_parser(sub: Any, scenario_help: str) -> None:
    """The ``export-ssp`` sub-command's arguments."""
    ex = sub.add_parser(
        "export-ssp",
        help="write the scenario as an SSP 1.0 package (its FMUs, SystemStructure.ssd)",
    )
    ex.add_argument("scenario", help=scenario_help)
    add_set_option(ex, "a parameter or setting first")
    ex.add_argument("--out", required=True, help="the package to write, e.g. DIR/system.ssp")


def cmd_export_ssp(args: argparse.Namespace) -> int:
    from .ssp_export import export_ssp

    scenario = api.load(args.scenario, args.set)
    path = export_ssp(scenario, args.out)
    units = len(scenario.graph.units) + len(scenario.fmus)
    print(f"{scenario.name}: {units} components, SSP 1.0 -> {path}")
    return 0
