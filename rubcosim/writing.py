"""Writing results: an output directory filled elsewhere and moved into place when
complete, a run's ``results.csv``, ``report.json`` and plots."""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .runner import CosimRun, ScenarioRun, report
from .scenario import ScenarioError


class OutputPathError(ScenarioError):
    """The output directory cannot be used (nothing has been written)."""


def ensure_writable_folder(folder: Path, given: str | Path) -> None:
    """Create ``folder`` (with its parents) if need be and make sure a file can be made in
    it; else :class:`OutputPathError` naming ``--out given`` and the system's reason.
    Checked before a run, so that a run that cannot keep its results does not start."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        Path(tempfile.mkdtemp(prefix=".rubcosim-probe-", dir=folder)).rmdir()
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise OutputPathError(f"--out {given}: cannot write in {folder} ({reason})") from exc


def check_output_dir(out_dir: str | Path) -> Path:
    """Refuse an output path that is a file, the working directory or one of its
    parents, a non-empty directory that is not an earlier result, or one whose parent
    cannot be created or written in."""
    out = Path(out_dir)
    resolved = out.resolve()
    if out.exists() and not out.is_dir():
        raise OutputPathError(f"--out {out_dir}: exists and is not a directory")
    cwd = Path.cwd().resolve()
    if resolved == cwd or resolved in cwd.parents:
        raise OutputPathError(f"--out {out_dir}: is the working directory or contains it")
    if out.is_dir() and any(out.iterdir()) and not (out / "report.json").is_file():
        # Only an earlier result (it has a report.json) is ever replaced.
        raise OutputPathError(
            f"--out {out_dir}: is a non-empty directory that holds no earlier result"
        )
    ensure_writable_folder(out.parent, out_dir)
    return out


def write_directory(out_dir: str | Path, fill: Callable[[Path], Any]) -> Path:
    """Let ``fill(tmp)`` write a fresh directory, then move it to ``out_dir``, replacing
    an earlier result only once the new one is complete."""
    out = check_output_dir(out_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        fill(tmp)
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
            out.rename(old / out.name)
            tmp.rename(out)
            shutil.rmtree(old)
        else:
            tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def output_table(run: ScenarioRun | CosimRun) -> tuple[list[np.ndarray], list[str]]:
    """The columns of ``results.csv``: the output grid up to the time reached (s), then
    one per recorded output (a text array for a String output of a foreign FMU); and
    the column names."""
    names = run.scenario.outputs
    keep = run.time <= run.result.t_reached + 1e-12
    return [run.time[keep], *(run.series(n)[keep] for n in names)], ["time", *names]


def write_csv(run: ScenarioRun | CosimRun, path: str | Path) -> Path:
    """Write ``results.csv``: time, then every recorded output; numbers with 17
    significant digits, texts quoted (double quotes doubled inside, as RFC 4180)."""
    columns, header = output_table(run)
    if all(c.dtype.kind == "f" for c in columns):
        table = np.column_stack(columns)
        np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
        return Path(path)
    cells = [
        ['"' + str(v).replace('"', '""') + '"' for v in c]
        if c.dtype.kind in "UO"
        else [f"{v:.17g}" for v in c]
        for c in columns
    ]
    lines = [",".join(header), *(",".join(row) for row in zip(*cells, strict=True))]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_results(run: ScenarioRun | CosimRun, out_dir: str | Path, plots: bool = True) -> Path:
    """Write ``results.csv``, ``report.json`` and (``plots``) the plots into a fresh
    directory, then move it to ``out_dir``.

    A previous result in ``out_dir`` is replaced only once the new one is
    complete, so an interrupted run never leaves a half-written result.
    """

    def fill(tmp: Path) -> None:
        write_csv(run, tmp / "results.csv")
        (tmp / "report.json").write_text(json.dumps(report(run), indent=2) + "\n", encoding="utf-8")
        if plots:
            from .plots import scenario_plots  # matplotlib only when plotting

            scenario_plots(run, tmp)

    return write_directory(out_dir, fill)
