"""Shared fixtures."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every FMU, built once per test process: model identifier -> path."""
    from rubcosim.fmus.build import build_fmus

    out = tmp_path_factory.mktemp("fmus")
    return {path.stem: path for path in build_fmus(out)}


# The modules whose tests take longest (pytest --durations=0, warm cache, 2026-11-28),
# longest first: run first, so that the two workers of `make test` (pytest -n 2) do not
# end with one of them alone on a long test while the other has nothing left.
LONGEST_FIRST = (
    "test_flat_master.py",
    "test_fmus.py",
    "test_fmus_in_other_tools.py",
    "test_fmi_sequences.py",
    "test_cosim.py",
    "test_etdas.py",
    "test_api.py",
    "test_engines.py",
    "test_benchmark_scripts.py",
    "test_trusted_ties.py",
    "test_analysis.py",
    "test_foreign_fmu.py",
    "test_scenario_cli.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put the longest modules first (each module's tests stay together and in order)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
