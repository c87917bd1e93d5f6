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


def test_the_flip_curve_in_two_parameters_is_the_closed_forms(flip_branch):
    """The flip followed in (w, r) from r = 0.8 to 0.4: at every point of the curve the
    closed form's flip frequency for that r, to 1e-8."""
    curve = rc.bifurcation_curve(flip_branch, "flip", "oscillator.restitution", 0.4)
    assert curve.stop_reason == "reached the end of the range"
    assert curve.params2[0] == 0.8 and curve.params2[-1] == pytest.approx(0.4, 1e-12)
    for p in curve.points:
        case = {**CASE, "r": p.param2}
        w = brentq(lambda w, c=case: flip_test(w, d=0.0, **c), p.param - 0.05,
                   p.param + 0.05, xtol=1e-14)  # fmt: skip
        assert abs(p.param - w) < 1e-8
        assert abs(np.min(np.abs(p.multipliers + 1.0))) < 1e-7


def test_the_fold_curve_in_two_parameters_is_the_closed_forms(fold_branch):
    """The fold followed in (w, d): the quadratic's discriminant is zero along it."""
    curve = rc.bifurcation_curve(fold_branch, "fold", "oscillator.barrier", -0.4,
                                 max_points=40)  # fmt: skip
    assert len(curve.points) >= 10
    for p in curve.points:
        w = brentq(lambda w, d=p.param2: discriminant(w, d=d, **CASE), p.param - 0.02,
                   p.param + 0.02, xtol=1e-14)  # fmt: skip
        assert abs(p.param - w) < 1e-8


def test_grazing_of_the_non_impacting_orbit_is_where_its_amplitude_is_the_gap():
    """The non-impacting orbit x = R(w) cos(w t - psi) continued down in w toward its
    stop at x = 0.5 grazes where R(w) = 0.5, with the square-root law there."""
    sc = _scenario(0.5, 2.5)
    branch = rc.continuation(sc, PARAM, 2.5, 1.5)
    assert {p.impacts for p in branch.points} == {0}
    assert branch.stop_reason.startswith("grazing")
    (graze,) = branch.special_of("grazing")
    exact = brentq(lambda w: 1.0 / math.hypot(1.0 - w * w, 0.1 * w) - 0.5, 1.6, 2.0,
                   xtol=1e-15)  # fmt: skip
    assert graze.details["located"] and abs(graze.param - exact) < 1e-8
    assert abs(graze.details["sqrt_law"]["exponent"] - 0.5) < 0.05


def test_branch_switching_follows_the_period_doubling_cascade_to_real_attractors():
    """Switching at each first flip gives branches of periods 2, 4, 8; every branch's
    most stable orbit is an attractor: the map iterated from it, perturbed by 1e-6,
    comes back to it (a second method: direct integration, no Newton)."""
    from rubcosim.analysis.maps import StroboscopicMap

    sc = _scenario(0.0, 2.0)
    branch = rc.continuation(sc, PARAM, 2.0, 3.0, doublings=3, max_points=150)
    cascade = branch.cascade
    assert [b.period for b in cascade.branches] == [1, 2, 4, 8]
    mu = cascade.flip_params
    assert len(mu) == 4 and np.all(np.diff(mu) > 0) and mu[0] == branch.special[0].param
    for b in cascade.branches:
        assert {p.impacts for p in b.points} == {b.period}  # one impact per period
        p = min((q for q in b.points if q.stable), key=lambda q: q.spectral_radius)
        system = sc.with_params({PARAM: p.param}).system
        k = int(np.ceil(np.log(1e-10) / np.log(max(p.spectral_radius, 1e-3))))
        orbit = StroboscopicMap(system, 1e-12).orbit(p.state + 1e-6, skip=b.period * k - 1)
        assert np.max(np.abs(orbit.final_state - p.state)) < 1e-8
        assert len(b.section_points) == len(b.points)
        assert b.section_points[0].shape == (b.period, 2)


@pytest.mark.parametrize(
    ("name", "settings", "stop"),
    [
        ("impact_oscillator_linear", {"oscillator.damping": 0.1}, 2.6),
        ("jeffcott_rigid_stator", {}, 340.0),
    ],
)
def test_stable_orbits_of_a_branch_are_what_a_sweep_settles_onto(name, settings, stop):
    """Brute force: a sweep (settling from the previous value's state, no Newton) over
    some of the branch's parameter values ends on the branch's stable orbits, to 1e-8 of
    the state scales: an impact oscillator's impacting orbit, and the Jeffcott rotor in
    full annular rub on its rigid stator (sustained sliding contact at the section)."""
    sc = rc.load(name, set=settings)
    branch = rc.continuation(sc, *(("oscillator.forcing_frequency", 2.0) if "oscillator" in name
                                   else ("rotor.speed", None)), stop)  # fmt: skip
    stable = [p for p in branch.points if p.stable][:: max(1, len(branch.points) // 6)]
    assert len(stable) >= 3
    values = [p.param for p in stable]
    if values[0] > values[-1]:
        stable, values = stable[::-1], values[::-1]
    result = rc.sweep(sc, branch.param, values, periods=2, discard=600, rtol=1e-12)
    scale = sc.system.state_scale
    for i, p in enumerate(stable):
        settled = result.points["up"][i, -1]
        assert np.max(np.abs(settled - p.state) / scale) < 1e-8, (name, p.param)


def test_feng_yangs_saddles_sit_where_their_branches_meet_the_attractors_branches():
    """Feng & Yang's case, from the paper's cells only (Figure 1, Table 1):

    * Newton from the centre of S2's cell finds a saddle in that cell; its branch (the
      symmetric non-impacting orbit) meets the branch of P2 at the two symmetry-breaking
      points where P2's branch turns: both located, from the two branches, at the same
      parameter and state; P2's branch, turned, comes back to the paper's w at P3;
    * Newton from S1's cell finds an impacting saddle there; lowering w, it meets a fold
      and comes back, through a flip, to the paper's w at a flip-unstable impacting
      orbit inside the cells of the chaotic attractor P1;
    * P4's impacting orbit meets a fold above the paper's w."""
    from rubcosim.analysis.published import PUBLISHED, hsu_centre

    paper = PUBLISHED["feng_yang_attractors"]
    grid = paper["grid"]
    width = np.array([(grid[3] - grid[2]) / grid[0], (grid[5] - grid[4]) / grid[1]])
    centre = {k: hsu_centre(v[0], grid)[0] for k, v in paper["saddles"].items()}
    centre.update({k: hsu_centre(v[0], grid)[0] for k, (v, _) in paper["attractors"].items()})
    sc = rc.load("feng_yang_attractors")
    w0 = sc.units["oscillator"]["forcing_frequency"]

    def inside(state, name, cells=1.0):
        return np.all(np.abs(state - centre[name]) <= cells * width)

    s2 = rc.continuation(sc, PARAM, None, 0.55, y0=centre["S2"])
    s2_up = rc.continuation(sc, PARAM, None, 0.85, y0=centre["S2"])
    assert inside(s2.points[0].state, "S2") and s2.points[0].multipliers[0].real > 1.0
    p2 = rc.continuation(sc, PARAM, None, 0.55, y0=centre["P2"])
    p2_up = rc.continuation(sc, PARAM, None, 0.85, y0=centre["P2"])
    assert inside(p2.points[0].state, "P2", 0.5) and p2.points[0].stable
    for on_s2, on_p2 in ((s2, p2), (s2_up, p2_up)):
        (bp,) = on_s2.special_of("branch-point")
        fold = on_p2.special_of("fold")[-1]  # P2's own turn at the symmetry breaking
        # two branches cross at a branch point: located less precisely than a fold
        assert abs(bp.param - fold.param) < 1e-6
        assert np.max(np.abs(bp.state - fold.state)) < 1e-4
    assert p2_up.params[-1] == pytest.approx(w0, abs=1e-12)
    assert inside(p2_up.points[-1].state, "P3", 0.5) and p2_up.points[-1].stable

    s1 = rc.continuation(sc, PARAM, None, 0.55, y0=_saddle_in_cell(sc, centre["S1"], width))
    first = s1.points[0]
    assert inside(first.state, "S1") and first.impacts == 1 and first.multipliers[0].real > 1
    kinds = [s.kind for s in s1.special]
    assert kinds == ["fold", "flip"] and s1.special[0].param < w0
    last = s1.points[-1]
    assert last.param == pytest.approx(w0, abs=1e-12) and last.impacts == 1
    assert last.multipliers[0].real < -1.0
    p1_cells = hsu_centre(paper["attractors"]["P1"][0], grid)
    assert np.min(np.max(np.abs(p1_cells - last.state) / width, axis=1)) <= 1.0

    p4 = rc.continuation(sc, PARAM, None, 0.85, y0=centre["P4"])
    assert inside(p4.points[0].state, "P4", 0.5) and p4.points[0].impacts == 1
    assert [s.kind for s in p4.special] == ["fold"] and p4.special[0].param > w0
    assert not p4.stable[-1]


def _saddle_in_cell(sc, centre, width, n=5):
    """A saddle found by Newton from a start in the cell of ``centre`` (an n x n grid of
    starts; the cell is the paper's, the first start whose Newton ends in it wins)."""
    problem = OrbitProblem(sc, PARAM)
    w0 = problem.value()
    offsets = (np.arange(n) + 0.5) / n - 0.5
    for dx in offsets:
        for dv in offsets:
            start = centre + np.array([dx, dv]) * width
            try:
                y, lin, _ = problem.newton(start, w0)
            except MapError:
                continue
            lam = np.linalg.eigvals(lin.monodromy)
            if np.all(np.abs(y - centre) <= width) and np.max(np.abs(lam)) > 1.0:
                return y
    raise AssertionError(f"no saddle found by Newton in the cell of {centre}")


def test_in_the_forcing_amplitude_p4_is_born_at_a_fold_and_p3_dies_grazing():
    """Feng & Yang's case continued in f: P4 (one impact a period) is born at a fold
    below the paper's f = 0.77 and P3 (no impact) grazes the stop above it; checked by
    direct simulation on both sides of each (no Newton): just inside, the motion from
    the branch's orbit settles onto an orbit of the branch's impacts; just outside, P4's
    is gone (the motion leaves its impacting orbit) and P3's impacts."""
    from rubcosim.analysis.maps import StroboscopicMap

    sc = rc.load("feng_yang_attractors")
    amp = "oscillator.forcing_amplitude"
    p4 = rc.continuation(sc, amp, None, 0.3, y0=[0.9625, 0.33])
    p3 = rc.continuation(sc, amp, None, 1.2, y0=[0.7675, 0.51])
    (fold,) = p4.special_of("fold")
    (graze,) = p3.special_of("grazing")
    assert fold.param < 0.77 < graze.param and graze.details["located"]

    def settles(f, y, periods=1500):
        system = sc.with_params({amp: f}).system
        orbit = StroboscopicMap(system, 1e-10).orbit(y, skip=periods, keep=20)
        return orbit.points, orbit.impacts

    pts, imp = settles(fold.param + 1e-3, fold.state)
    assert np.all(imp == 1) and np.ptp(pts, axis=0).max() < 1e-6  # a 1-1 orbit
    pts, imp = settles(fold.param - 1e-3, fold.state)
    assert not (np.all(imp == 1) and np.ptp(pts, axis=0).max() < 1e-6)
    pts, imp = settles(graze.param - 1e-3, graze.state)
    assert np.all(imp == 0) and np.ptp(pts, axis=0).max() < 1e-6  # a 1-0 orbit
    _, imp = settles(graze.param + 1e-3, graze.state, periods=50)
    assert imp.sum() > 0


def test_the_rotors_free_whirl_grazes_the_stator_at_the_rub_onset_speed():
    """The Jeffcott rotor's unbalance whirl continued up in speed reaches the stator where
    its radius e s^2 / sqrt((1 - s^2)^2 + (2 z s)^2) equals the clearance (the lower root
    of rub_onset_speed_ratios' quadratic, solved here apart from it), to 1e-8."""
    sc = rc.load("jeffcott_rigid_stator", set={"rotor.speed": 200.0})
    branch = rc.continuation(sc, "rotor.speed", None, 300.0)
    (graze,) = branch.special_of("grazing")
    wn, z, rho = math.sqrt(1e6 / 10.0), 316.227766 / (2.0 * math.sqrt(1e6 * 10.0)), 0.5
    s = brentq(lambda s: rho * s * s / math.hypot(1 - s * s, 2 * z * s) - 1.0, 0.5, 1.0,
               xtol=1e-15)  # fmt: skip
    assert graze.details["located"]
    assert abs(graze.param - s * wn) < 1e-8 * s * wn


def test_a_branch_starts_from_a_saddle_a_basins_run_found(tmp_path):
    """`--start-from` a basins output: its first saddle (Feng & Yang's S2 on a coarse
    grid) starts the branch; a bad folder or index is one error naming the flag."""
    basins_out = tmp_path / "basins"
    assert main(["basins", "feng_yang_attractors", "--grid", "40x40", "--samples", "2",
                 "--check", "0", "--out", str(basins_out), "--no-progress"]) == 0  # fmt: skip
    report = json.loads((basins_out / "report.json").read_text())
    saddle = next(p for p in report["fixed_points"] if p["saddle"])
    out = tmp_path / "branch"
    args = ["continue", "feng_yang_attractors", "--param", PARAM, "--to", "0.7"]
    assert main([*args, "--start-from", str(basins_out), "--out", str(out)]) == 0
    with open(out / "branch.csv") as f:
        first = next(csv.DictReader(f))
    state = [float(first[n]) for n in ("oscillator.x", "oscillator.v")]
    assert np.max(np.abs(np.array(state) - saddle["state"])) < 1e-8
    assert main([*args, "--start-from", str(tmp_path), "--out", str(tmp_path / "x")]) == 2
    bad = ["--start-from", str(basins_out), "--fixed-point", "99", "--out", str(tmp_path / "y")]
    assert main([*args, *bad]) == 2


def test_grazing_of_an_elastic_stop_follows_the_three_halves_law():
    """The same non-impacting orbit against an elastic stop (k_s = 100 at x = 0.5): it
    grazes where R(w) = 0.5, as for the rigid stop, and the map's deviation grows as the
    penetration depth to the power 3/2 (the force is continuous, its derivative jumps)."""
    sc = rc.load("impact_oscillator_linear", set={
        "oscillator.damping": 0.1, "oscillator.barrier": 0.5, PARAM: 2.5,
        "oscillator.stop": "elastic_one_sided", "oscillator.stop_stiffness": 100.0,
    })  # fmt: skip
    branch = rc.continuation(sc, PARAM, 2.5, 1.5)
    (graze,) = branch.special_of("grazing")
    exact = brentq(lambda w: 1.0 / math.hypot(1.0 - w * w, 0.1 * w) - 0.5, 1.6, 2.0,
                   xtol=1e-15)  # fmt: skip
    assert graze.details["located"] and abs(graze.param - exact) < 1e-8
    law = graze.details["sqrt_law"]
    assert law["expected"] == 1.5 and abs(law["exponent"] - 1.5) < 0.05
