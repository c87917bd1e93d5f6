"""What every benchmark result carries: commit, date, machine and library versions."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent


def git_commit() -> str:
    """The checked-out commit, with ``+dirty`` when tracked files differ from it (other
    than the results files the benchmarks themselves write)."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
             ":!benchmarks/results"],
            cwd=REPO, capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def stamp(**settings: Any) -> dict[str, Any]:
    """The ``meta`` block of a result file, with the benchmark's own settings."""
    import numba
    import numpy
    import scipy

    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "git_commit": git_commit(),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        **settings,
    }


def stamp_line(meta: dict[str, Any]) -> str:
    """One line of Markdown saying where and when a table was measured."""
    dirty = " (with uncommitted changes)" if meta["git_commit"].endswith("+dirty") else ""
    return (
        f"{meta['date']}, {meta['cpu_count']} CPUs, Python {meta['python']}, numpy "
        f"{meta['numpy']}, scipy {meta['scipy']}, numba {meta['numba']}, commit "
        f"{meta['git_commit'][:10]}{dirty}."
    )
