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
