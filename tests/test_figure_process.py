"""The figures' helper process (rubcosim.figure_process): wiring tests.

It draws in another process, and whatever goes wrong there ends with the figure
drawn in this one (an error of the drawing itself raised here)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rubcosim.figure_process import FigureProcess


def write_pid(path: Path) -> None:
    path.write_text(str(os.getpid()))


def fail_in_child(path: Path, parent: int) -> None:
    if os.getpid() != parent:
        raise RuntimeError("drawing failed in the helper")
    path.write_text(str(os.getpid()))


def always_fail(path: Path) -> None:
    raise ValueError(f"cannot draw {path.name}")


def test_the_figure_is_drawn_by_the_helper(tmp_path: Path) -> None:
    with FigureProcess() as figures:
        figures.submit(write_pid, tmp_path / "a.txt")
        figures.wait()
    assert int((tmp_path / "a.txt").read_text()) != os.getpid()


def test_a_failure_in_the_helper_draws_the_figure_here(tmp_path: Path) -> None:
    with FigureProcess() as figures:
        figures.submit(fail_in_child, tmp_path / "b.txt", os.getpid())
        figures.wait()
        # and the next figure too: the helper is gone
        figures.submit(write_pid, tmp_path / "c.txt")
        figures.wait()
    assert int((tmp_path / "b.txt").read_text()) == os.getpid()
    assert int((tmp_path / "c.txt").read_text()) == os.getpid()


def test_a_helper_that_died_leaves_the_figure_to_this_process(tmp_path: Path) -> None:
    with FigureProcess() as figures:
        figures._proc.kill()
        figures._proc.join()
        figures.submit(write_pid, tmp_path / "d.txt")
        figures.wait()
    assert int((tmp_path / "d.txt").read_text()) == os.getpid()


def test_an_error_of_the_drawing_itself_is_raised_here(tmp_path: Path) -> None:
    with FigureProcess() as figures:
        figures.submit(always_fail, tmp_path / "e.png")
        with pytest.raises(ValueError, match="cannot draw e.png"):
            figures.wait()
