"""``rubcosim check`` on a chaotic motion: how much of the difference chaos accounts for
(:mod:`rubcosim.chaos_check`)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rubcosim import api
from rubcosim.chaos_check import distribution_distance, separation, summary
from rubcosim.cli import main

# the offset rigid stator inside its chaotic band (issue 49: a worst relative difference
# of 2.65e-3 and 181 against 198 impacts, printed as a plain error)
CHAOTIC = {"rotor.speed": 360.0, "sim.t_end": 0.2}


@pytest.fixture(scope="module")
def chaotic_check():
    return api.check("jeffcott_offset_rigid_stator", "direct", set=CHAOTIC)


def test_a_sensitive_check_is_within_the_peer_and_says_so(chaotic_check):
    """The co-simulation differs from the reference as much as the accurate engine at the
    co-simulation's tolerance does (a second, monolithic integration), and the largest
    Lyapunov exponent over the window is positive over more than one e-folding: the
    report calls the motion chaotic and the difference within the peer's."""
    chaos = chaotic_check.chaos
    assert chaotic_check.worst_rel_error > 1e-4  # a difference a plain check reports
    assert chaos["verdict"] == "chaotic, within the peer", chaos
    assert chaos["largest_lyapunov_exponent"] > 0.0
    assert chaos["e_foldings"] > 1.0
    assert chaos["peer"]["worst_rel_error"] > 100.0 * chaos["peer"]["rtol"]
    assert chaos["before_horizon"]["cosim"] <= 10.0 * chaos["before_horizon"]["peer"]


def test_the_peer_is_the_accurate_engine_at_the_cosimulations_tolerance(chaotic_check):
    """The peer's figure is the difference of an independent run of the accurate engine
    at cosim.rtol from the reference, over the check's grid."""
    chaos = chaotic_check.chaos
    sc = chaotic_check.scenario
    r = chaos["peer"]["rtol"]
    peer = api.simulate(api.load(sc.name, {**CHAOTIC, "sim.rtol": r, "sim.atol": r}),
                        engine="accurate")  # fmt: skip
    curve = separation(chaotic_check.reference.result, peer.run.result, list(sc.outputs),
                       chaotic_check.rows)  # fmt: skip
    assert curve.max() == chaos["peer"]["worst_rel_error"]


def test_a_coupling_error_on_a_chaotic_motion_is_beyond_the_peer():
    """A master without event handling at a fixed step differs more than a correct
    integration at its tolerance: the check says so, chaos or not."""
    bad = {**CHAOTIC, "cosim.events": "off", "cosim.adaptive": False}
    chaos = api.check("jeffcott_offset_rigid_stator", "direct", set=bad).chaos
    assert chaos["verdict"] == "chaotic, beyond the peer", chaos
    assert chaos["cosim_over_peer"] > 10.0


def test_a_regular_check_computes_no_exponent_and_the_cli_prints_one_line(tmp_path, capsys):
    """The flagship's motion is periodic: the peer stays within its tolerance's reach,
    no Lyapunov exponent is computed, and the terminal gets no chaos line; the report
    holds the block."""
    out = tmp_path / "check"
    args = ["check", "jeffcott_rigid_stator", "--set", "sim.t_end=0.02", "--out", str(out)]
    assert main([*args, "--no-plots", "--no-progress"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["chaos"]["verdict"] == "regular"
    assert report["chaos"]["largest_lyapunov_exponent"] is None
    assert "chaotic" not in capsys.readouterr().out


def test_the_cli_prints_the_chaos_line(tmp_path, capsys):
    sets = [f"{k}={v}" for k, v in CHAOTIC.items()]
    out = tmp_path / "check"
    args = ["check", "jeffcott_offset_rigid_stator", "--out", str(out), "--no-plots"]
    assert main([*args, "--no-progress", *[a for s in sets for a in ("--set", s)]]) == 0
    printed = capsys.readouterr().out
    assert "the motion is sensitive (largest Lyapunov exponent" in printed
    assert "e-foldings: chaotic)" in printed
    assert "what a correct integration does, not a coupling error" in printed


LONG = {**CHAOTIC, "sim.t_end": 1.0}  # past the peer's horizon (about 0.34 s)


def test_past_the_horizon_a_correct_cosimulation_agrees_in_statistics():
    """Over 1 s the peer itself strays to the size of the motion; after its horizon the
    co-simulation's impact rate and the distributions of its outputs match the
    reference's as closely as the peer's do (two correct integrations of one chaotic
    motion)."""
    chaos = api.check("jeffcott_offset_rigid_stator", "direct", set=LONG).chaos
    assert chaos["verdict"] == "chaotic, within the peer", chaos
    assert 0.2 < chaos["horizon_s"] < 0.6
    beyond = chaos["beyond_horizon"]
    assert beyond["compared"] and beyond["agree"], beyond
    assert beyond["from_s"] == chaos["horizon_s"] and beyond["output_times"] > 1000
    co, peer = beyond["cosim"], beyond["peer"]
    assert co["reference_impact_rate"] == peer["reference_impact_rate"] > 100.0
    assert co["impact_rate_rel_diff"] < 0.05 and co["distribution"] < 0.1


def test_past_the_horizon_a_broken_coupling_disagrees_in_statistics(capsys):
    """The master without event handling at a fixed step: beyond the peer before the
    horizon, and its statistics after it are not those of the motion."""
    bad = {**LONG, "cosim.events": "off", "cosim.adaptive": False}
    chaos = api.check("jeffcott_offset_rigid_stator", "direct", set=bad).chaos
    assert chaos["verdict"] == "chaotic, beyond the peer", chaos
    assert chaos["beyond_horizon"]["compared"] and not chaos["beyond_horizon"]["agree"]
    assert "the statistics DISAGREE" in summary(chaos)


def test_the_distribution_distance_is_the_kolmogorov_smirnov_statistic():
    """Values worked by hand: the largest gap between the two empirical distribution
    functions (a step of 1/n at each sample)."""
    a, b = np.array([1.0, 2.0, 3.0, 4.0]), np.array([2.5, 3.5])
    # at x = 2: F_a = 2/4, F_b = 0
    assert distribution_distance(a, b) == pytest.approx(0.5, abs=1e-15)
    assert distribution_distance(b, a) == pytest.approx(0.5, abs=1e-15)
    a = np.random.default_rng(7).normal(size=400)
    assert distribution_distance(a, a) == 0.0
    assert distribution_distance(a, a + 100.0) == 1.0
