"""Progress bars in simulated time: shown on a terminal for long runs, never otherwise,
and fed while a compiled engine runs (it releases the GIL)."""

from __future__ import annotations

import io
import re
import time

import pytest

from rubcosim import progress
from rubcosim.cli import main
from rubcosim.reference.simulate import simulate
from rubcosim.scenario import load_scenario


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _percentages(text: str) -> list[int]:
    return [int(p) for p in re.findall(r"(\d+)%\|", text)]


def test_bar_follows_the_simulated_time_on_a_terminal(monkeypatch):
    term = FakeTerminal()
    monkeypatch.setattr("sys.stderr", term)
    clock = {"t": 2.0}
    with progress.watch("run", 2.0, 4.0, lambda: clock["t"], delay=0.0, every=0.01):
        for t in (2.5, 3.0, 3.5):
            clock["t"] = t
            time.sleep(0.05)
    shown = _percentages(term.getvalue())
    assert "run" in term.getvalue() and 25 in shown and 50 in shown and 75 in shown


@pytest.mark.parametrize("tty, enabled", [(False, True), (True, False)])
def test_nothing_is_printed_off_a_terminal_or_when_turned_off(monkeypatch, tty, enabled):
    stream = FakeTerminal() if tty else io.StringIO()
    monkeypatch.setattr("sys.stderr", stream)
    with progress.watch("run", 0.0, 1.0, lambda: 0.5, enabled=enabled, delay=0.0, every=0.01):
        time.sleep(0.05)
    assert stream.getvalue() == ""


def test_fast_engine_reports_progress_while_it_runs(monkeypatch):
    # the compiled engine runs without the GIL: the watcher sees intermediate times
    term = FakeTerminal()
    monkeypatch.setattr("sys.stderr", term)
    monkeypatch.setattr(progress, "DELAY_S", 0.0)
    monkeypatch.setattr(progress, "EVERY_S", 0.002)
    sc = load_scenario("impact_duffing", ["sim.t_end=40000.0"])
    simulate(sc.system, 40000.0, engine="fast", rtol=1e-10, output_step=1.0, progress=True)
    shown = _percentages(term.getvalue())
    assert any(0 < p < 100 for p in shown), term.getvalue()[-500:]


def test_cli_run_and_check_take_no_progress_and_print_no_bar_off_a_terminal(tmp_path, capsys):
    args = ["impact_oscillator_linear", "--set", "sim.t_end=20.0"]
    assert main(["run", *args, "--out", str(tmp_path / "a"), "--no-progress"]) == 0
    assert main(["run", *args, "--out", str(tmp_path / "b")]) == 0
    assert main(["check", *args, "--out", str(tmp_path / "c"), "--no-progress"]) == 0
    assert "%|" not in capsys.readouterr().err
