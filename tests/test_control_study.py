"""The chaos control study: a chaotic rotor by its Lyapunov exponent, the target orbit
by Newton and Floquet, runs judged by their distance to the target and their force."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.control_study import judge, switch_on_times, uncontrolled
from rubcosim.analysis.errors import AnalysisError
from rubcosim.cli import main

SCENARIOS = Path(__file__).parents[1] / "scenarios"
RIGID = SCENARIOS / "jeffcott_chaos_control.toml"
SMALL = dict(periods=60, lyapunov_periods=300, transient=100, workers=1)


def test_switch_on_times_spread_over_the_interval():
    assert np.allclose(switch_on_times("1:2:5"), [1.0, 1.25, 1.5, 1.75, 2.0])
    assert np.allclose(switch_on_times((3.0, 3.0, 1)), [3.0])
    for bad in ("1:2", "a:b:c", "2:1:3", "1:2:0", "-1:2:3"):
        with pytest.raises(AnalysisError, match="--switch-on"):
            switch_on_times(bad)


def test_the_uncontrolled_scenario_drops_the_controller_and_its_outputs():
    free = uncontrolled(rc.load(RIGID, {"controller.gain": 10.0, "rotor.speed": 400.0}))
    assert "controller" not in free.units and not free.system.has_delay
    assert all(not n.startswith("controller.") for n in free.outputs)
    assert free.graph.units["rotor"].params["speed"] == 400.0  # other overrides kept
    with pytest.raises(AnalysisError, match="no \\[units.controller\\]"):
        uncontrolled(free)


@pytest.fixture(scope="module")
def study():
    # two gains: the scenario's, which catches the orbit, and one 100 times weaker
    return rc.control_study(RIGID, "1.528:1.7:2", gains=[9.48683298, 948.683298], **SMALL)


def test_the_uncontrolled_rotor_is_chaotic_and_its_exponents_sum_to_liouville(study):
    lyap = study.lyapunov
    assert lyap.exponents[0] > 10.0  # 1/s; +31.7 over 3000 periods
    # second method: the sum of the spectrum is the mean phase-space contraction
    assert lyap.exponents.sum() == pytest.approx(lyap.liouville, rel=1e-6)


def test_the_target_is_an_unstable_period_one_orbit(study):
    f = study.target
    assert f is not None and f.period == 1 and f.residual < 1e-8
    assert not f.stable and f.spectral_radius > 1.0
    assert f.impacts == 2  # two impacts per period, as the scenario's comment says


def test_runs_are_judged_by_distance_and_force(study):
    by_gain = {}
    for r in study.runs:
        by_gain.setdefault(r.gain, []).append(r)
    caught = by_gain[948.683298]
    assert all(r.converged and 0 <= r.periods_to_converge < 50 for r in caught)
    assert all(r.final_distance < 1e-3 and r.final_force < 1e-3 * 948.683298 for r in caught)
    # a gain too weak to catch the orbit is reported as failing, not hidden
    weak = by_gain[9.48683298]
    assert not any(r.converged for r in weak)
    assert all(r.periods_to_converge == -1 and r.final_distance > 1e-3 for r in weak)
    rates = study.success_rates()
    assert rates[(948.683298, 0.0)] == 1.0 and rates[(9.48683298, 0.0)] == 0.0


def test_a_run_that_stopped_fails():
    result = {
        "distance": np.array([0.5, 1e-5, 1e-6]),
        "force": np.array([math.nan]),
        "ok": np.array([False]),
        "message": np.array(["event limit"]),
    }
    verdict = judge(1.0, 0.0, 0.0, result, 1.0, hold=2)
    assert not verdict.converged and verdict.status == "event limit"


def test_control_study_refuses_what_it_cannot_study():
    with pytest.raises(AnalysisError, match="controller.memory"):
        rc.control_study(RIGID, "1.5:1.6:2", memories=[1.0], **SMALL)
    with pytest.raises(AnalysisError, match="controller.delay"):
        rc.control_study(RIGID, "1.5:1.6:2", set={"controller.delay": 0.02}, **SMALL)
    with pytest.raises(AnalysisError, match="no \\[units.controller\\]"):
        rc.control_study(SCENARIOS / "jeffcott_rigid_stator.toml", "0:1:2", **SMALL)


def test_cli_control_study_writes_report_table_and_figure(tmp_path, capsys):
    argv = ["control-study", str(RIGID), "--switch-on", "1.528:1.6:2", "--periods", "40"]
    argv += ["--lyapunov-periods", "200", "--transient", "100", "--workers", "1"]
    argv += ["--memory", "0,0.3", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "Lyapunov exponents" in text and "target: period-1 orbit" in text
    report = json.loads((tmp_path / "report.json").read_text())
    assert len(report["runs"]) == 4 and len(report["success_rates"]) == 2
    assert (tmp_path / "runs.csv").read_text().count("\n") == 5
    assert (tmp_path / "success.png").stat().st_size > 10_000
    assert main(["control-study", str(RIGID), "--switch-on", "x", "--out", str(tmp_path)]) == 2


def test_position_feedback_that_cannot_hold_the_target_is_reported_failing():
    # position feedback K = 1e6 N/m (as stiff as the shaft) on the chaotic rotor: the
    # delayed spring pumps energy in and the motion ends far from the target (violent
    # impacts); every run says so
    study = rc.control_study(
        RIGID, "1.528:1.6:2", gains=[1e6], set={"controller.feedback": "position"}, **SMALL
    )
    assert study.target is not None and len(study.runs) == 2
    for run in study.runs:
        assert not run.converged and run.periods_to_converge == -1
        assert run.status == "ok" and run.final_distance > 0.1
    assert study.success_rates() == {(1e6, 0.0): 0.0}


def test_lyapunov_of_a_controlled_scenario_without_its_controller(capsys):
    # the spectrum of the scenario without its controller is the control study's; with
    # the controller the delay equation is refused, pointing at --uncontrolled
    direct = rc.lyapunov(RIGID, periods=50, transient=20, uncontrolled=True)
    free = rc.lyapunov(uncontrolled(rc.load(RIGID)), periods=50, transient=20)
    assert np.array_equal(direct.exponents, free.exponents)
    with pytest.raises(AnalysisError, match="--uncontrolled"):
        rc.lyapunov(RIGID, periods=5, transient=1)
    argv = ["lyapunov", str(RIGID), "--uncontrolled", "--periods", "50", "--transient", "20"]
    assert main(argv) == 0
    assert "without its controller" in capsys.readouterr().out
