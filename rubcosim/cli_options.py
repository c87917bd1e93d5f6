"""Options shared by the sub-commands of ``rubcosim``."""

from __future__ import annotations

import argparse


def add_set_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--set UNIT.PARAM=VALUE`` (repeatable): overrides of ``what``."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="UNIT.PARAM=VALUE",
        help=f"override {what} (repeatable)",
    )
