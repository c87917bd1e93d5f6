"""Options shared by the sub-commands of ``rubcosim``."""

from __future__ import annotations

import argparse

# the exit codes of ``rubcosim``: bad input (refused before anything ran), a failed run
EXIT_BAD_INPUT = 2
EXIT_RUN_FAILED = 3


def add_set_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--set UNIT.PARAM=VALUE`` (repeatable): overrides of ``what``."""
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="UNIT.PARAM=VALUE",
        help=f"override {what} (repeatable)",
    )


def plot_state_index(names: list[str], given: str | None) -> int:
    """The index of ``--plot-state`` among the state ``names`` (default: the first)."""
    from .scenario import ScenarioError

    if given is None:
        return 0
    if given not in names:
        raise ScenarioError(f"--plot-state {given!r}: not one of {', '.join(names)}")
    return names.index(given)
