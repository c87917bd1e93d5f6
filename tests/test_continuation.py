"""Continuation of impacting periodic orbits (``rubcosim continue``), checked against
the closed form of the linear impact oscillator's period-1 orbits (Shaw & Holmes 1983,
:mod:`impact_oscillator_closed_form`): the branch's states and multipliers, its flip and
its fold; Liouville's formula with the saltation matrix; and the bad inputs."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from impact_oscillator_closed_form import discriminant, flip_test, orbits
from scipy.optimize import brentq

import rubcosim as rc
from rubcosim.analysis.errors import AnalysisError, MapError
from rubcosim.analysis.orbit_problem import OrbitProblem
from rubcosim.cli import main
from rubcosim.scenario import ScenarioError

# x'' + 0.1 x' + x = cos(w t), stop at x = d, r = 0.8
CASE = {"a": 1.0, "b": 0.1, "f": 1.0, "r": 0.8}
PARAM = "oscillator.forcing_frequency"


def _scenario(d: float, w: float):
    return rc.load(
        "impact_oscillator_linear",
        set={"oscillator.damping": 0.1, "oscillator.barrier": d, PARAM: w},
    )


@pytest.fixture(scope="module")
def flip_branch():
    return rc.continuation(_scenario(0.0, 2.0), PARAM, 2.0, 2.8)


@pytest.fixture(scope="module")
def fold_branch():
    return rc.continuation(_scenario(-0.5, 3.0), PARAM, 3.0, 2.0)


def test_the_branch_is_the_closed_form_orbit_with_its_multipliers(flip_branch):
    """Every point's state on the section to 1e-8 and its multipliers to 1e-7."""
    assert flip_branch.stop_reason == "reached the end of the range"
    assert flip_branch.params[0] == 2.0 and flip_branch.params[-1] == pytest.approx(2.8, 1e-12)
    for p in flip_branch.points:
        exact = orbits(p.param, d=0.0, **CASE)[0]
        assert np.max(np.abs(p.state - exact["section"])) < 1e-8
        lam = np.sort_complex(exact["multipliers"])
        assert np.max(np.abs(np.sort_complex(p.multipliers) - lam)) < 1e-7
        assert p.impacts == 1 and p.residual < 1e-10


def test_the_flip_is_where_the_closed_form_has_a_multiplier_minus_one(flip_branch):
    w_flip = brentq(lambda w: flip_test(w, d=0.0, **CASE), 2.6, 2.7, xtol=1e-14)
    (flip,) = flip_branch.special
    assert flip.kind == "flip"
    assert abs(flip.param - w_flip) < 1e-8
    assert abs(flip.critical + 1.0) < 1e-7
    # stable before it, unstable after it
    before = flip_branch.params < flip.param
    assert flip_branch.stable[before].all() and not flip_branch.stable[~before].any()


def test_the_fold_is_where_the_two_closed_form_orbits_meet(fold_branch):
    """From w = 3 down, the stable orbit turns at the fold (the quadratic's discriminant
    zero) onto the unstable one, which goes back up to w = 3."""
    w_fold = brentq(lambda w: discriminant(w, d=-0.5, **CASE), 2.1, 2.25, xtol=1e-14)
    folds = fold_branch.special_of("fold")
    assert len(folds) == 1
    assert abs(folds[0].param - w_fold) < 1e-8
    assert abs(folds[0].critical - 1.0) < 1e-7
    assert fold_branch.params[-1] == pytest.approx(3.0, 1e-12)
    after = np.arange(len(fold_branch.points)) > folds[0].index
    assert fold_branch.stable[~after].all() and not fold_branch.stable[after].any()
    for p in fold_branch.points[-3:]:  # the unstable orbit: the quadratic's other root
        exact = orbits(p.param, d=-0.5, **CASE)[1]
        assert np.max(np.abs(p.state - exact["section"])) < 1e-8


def test_multipliers_product_is_liouvilles_with_the_saltation(fold_branch):
    """det(monodromy) = r^2 exp(-b T) for one impact per period (det S = r^2, and the
    flow's volume decays at the rate b), on both sides of the fold."""
    for p in fold_branch.points:
        T = 2.0 * math.pi / p.param
        expected = CASE["r"] ** 2 * math.exp(-CASE["b"] * T)
        assert abs(np.prod(p.multipliers).real - expected) < 1e-8 * expected


def test_bad_input_is_one_error_naming_it():
    sc = _scenario(0.0, 2.0)
    with pytest.raises(ScenarioError, match="oscillator.nonsense"):
        rc.continuation(sc, "oscillator.nonsense", 2.0, 2.5)
    with pytest.raises(ScenarioError, match="--to"):
        rc.continuation(sc, "oscillator.restitution", None, 1.5)
    with pytest.raises(MapError, match="delay-free"):
        rc.continuation("jeffcott_delayed_feedback", "rotor.speed", None, 400.0)
    with pytest.raises(AnalysisError, match="--start"):
        rc.continuation(sc, PARAM, 2.0, 2.5, y0=[0.0])


def test_a_start_that_does_not_converge_says_how_far_newton_got():
    problem = OrbitProblem(_scenario(0.0, 2.0), PARAM)
    with pytest.raises(MapError, match=r"residual .* after 1 iterations"):
        problem.newton(np.array([-3.0, 1.0]), 2.0, max_iter=1)


def test_the_command_writes_the_branch_table_report_and_figure(tmp_path):
    out = tmp_path / "branch"
    code = main(["continue", "impact_oscillator_linear", "--set", "oscillator.damping=0.1",
                 "--param", PARAM, "--from", "2.0", "--to", "2.8", "--out", str(out),
                 "--no-progress"])  # fmt: skip
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert [s["kind"] for s in report["special_points"]] == ["flip"]
    with open(out / "branch.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == report["points"] and PARAM in rows[0]
    assert (out / "branch.png").stat().st_size > 10_000
