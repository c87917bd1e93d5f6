"""The orchestrator's parts on their own: polynomials, step control, events,
connections, settings, evaluation order, input derivatives of units."""

from __future__ import annotations

import math
import os
import time

import pytest

from rubcosim.components.units import make_unit
from rubcosim.components.wiring import (
    Connection,
    CouplingError,
    apply_table,
    check_connections,
    default_connections,
)
from rubcosim.orchestrator.events import Indicator, crossing, locate, predicted_to_cross
from rubcosim.orchestrator.extrapolation import evaluate, polynomial
from rubcosim.orchestrator.master import CosimError, evaluation_order
from rubcosim.orchestrator.settings import CosimSettings, SettingsError, cosim_settings
from rubcosim.orchestrator.step_control import PIController


@pytest.mark.parametrize("n", [1, 2, 3])
def test_polynomial_reproduces_polynomials_of_its_degree(n):
    coeffs = [1.5, -2.0, 0.75][:n]

    def f(t):
        return sum(c * t**k for k, c in enumerate(coeffs))

    pts = [(t, f(t)) for t in (0.1, 0.25, 0.3)[:n]]
    t0 = 0.3
    v, d1, d2 = polynomial(pts, t0)
    assert v == pytest.approx(f(t0), rel=1e-13)
    assert d1 == pytest.approx(
        sum(k * c * t0 ** (k - 1) for k, c in enumerate(coeffs) if k), abs=1e-12
    )
    assert d2 == pytest.approx(2 * coeffs[2] if n == 3 else 0.0, abs=1e-12)
    assert evaluate(v, d1, d2, 0.2) == pytest.approx(f(0.5), rel=1e-12)
    with pytest.raises(ValueError, match="no coupling value"):
        polynomial([], 0.0)


def test_pi_controller_grows_on_small_errors_and_shrinks_on_rejection():
    pi = PIController(order=3)
    assert pi.accept(1e-4, 1e-6) == pytest.approx(5e-4)  # capped at max_factor
    assert pi.accept(1e-4, 0.1) < 1e-4  # the error rose sharply: the integral part brakes
    pi.accept(1e-4, 0.1)
    assert 1e-4 < pi.accept(1e-4, 0.1) < 5e-4  # a steady error below 1 lets the step grow
    assert pi.reject(1e-4, 8.0) == pytest.approx(1e-4 * 0.9 * 8.0 ** (-1 / 3))
    assert pi.reject(1e-4, math.inf) == pytest.approx(2e-5)
    pi.restart()
    assert pi.err_prev == 1e-4


GAP = Indicator("stator", "gap", -1, "impact", rate="gap_rate")


def test_crossing_brackets():
    assert crossing(GAP, 1.0, -1.0, 0.1, -20.0, -20.0) == (0.0, 0.1)
    assert crossing(GAP, 1.0, 2.0, 0.1, 10.0, 10.0) is None
    # dips below zero and comes back inside the step: the Hermite minimum is the far end
    lo, hi = crossing(GAP, 0.01, 0.01, 1.0, -1.0, 1.0)
    assert lo == 0.0 and 0.4 < hi < 0.6
    # starts on the crossed side moving back (just after an impact) and crosses again
    lo, hi = crossing(GAP, -1e-12, -0.01, 1.0, 1.0, -1.0)
    assert 0.4 < lo < 0.6 and hi == 1.0
    # without a rate only a sign change counts
    assert crossing(Indicator("s", "n", -1, "release"), 0.01, 0.01, 1.0) is None
    rising = Indicator("s", "gap", 1, "contact_off", rate="gap_rate")
    assert crossing(rising, -1.0, 1.0, 0.5, 4.0, 4.0) == (0.0, 0.5)


def test_prediction_is_conservative():
    assert predicted_to_cross(GAP, 1e-3, -1.0, 0.0, 1e-3)
    assert not predicted_to_cross(GAP, 1e-3, -0.1, 0.0, 1e-3)
    assert predicted_to_cross(GAP, 1e-3, 0.0, 1000.0, 1e-3)
    assert not predicted_to_cross(GAP, -1e-3, -1.0, 0.0, 1e-3)  # already beyond


@pytest.mark.parametrize("rate", ["gap_rate", None])
def test_locate_finds_the_root_to_the_tolerance(rate):
    ind = Indicator("u", "g", -1, "k", rate=rate)
    root = math.acos(0.3)

    def probe(t):
        return math.cos(t) - 0.3, -math.sin(t)

    t_ev, trials = locate(probe, ind, 0.0, 0.7, 0.0, 2.0, probe(2.0)[0], probe(2.0)[1], 1e-12)
    assert probe(t_ev)[0] <= 0.0  # on the far side
    assert abs(t_ev - root) < 1e-11
    assert trials <= (8 if rate else 40)


def test_default_connections_follow_the_roles():
    links = {c.target: c.sources for c in default_connections(
        {"rotor": "jeffcott", "stator": "rigid", "controller": "delayed_feedback"})}  # fmt: skip
    assert links["rotor.fx"] == ("stator.fx", "controller.ux")
    assert links["stator.other_fy"] == ("rotor.force_y", "controller.uy")
    assert links["controller.vx"] == ("rotor.vx",)
    two = {c.target: c.sources for c in default_connections({"rotor": "two_mass", "bearing": "x"})}
    assert two["bearing.x"] == ("rotor.journal_x",)
    assert two["rotor.journal_fy"] == ("bearing.fy",)
    assert default_connections({"oscillator": "impact"}) == []


def test_connection_tables_replace_disconnect_and_are_checked():
    base = default_connections({"rotor": "jeffcott", "stator": "elastic"})
    merged = {
        c.target: c.sources for c in apply_table(base, {"rotor.fx": [], "rotor.fy": "stator.fy"})
    }
    assert "rotor.fx" not in merged and merged["rotor.fy"] == ("stator.fy",)
    with pytest.raises(CouplingError, match="connections.rotor.fx must be"):
        apply_table(base, {"rotor.fx": 3})
    with pytest.raises(CouplingError, match="not of the form"):
        apply_table(base, {"rotorfx": ["stator.fx"]})
    ins = {"rotor": ["fx"], "stator": ["x"]}
    outs = {"rotor": ["x"], "stator": ["fx"]}
    for bad, msg in [
        (Connection("rotor.fz", ("stator.fx",)), "'fz' is not an input of rotor"),
        (Connection("casing.fx", ("stator.fx",)), "no unit 'casing'"),
        (Connection("rotor.fx", ("stator.fq",)), "'fq' is not an output of stator"),
        (Connection("rotor.fx", ("bearing.fx",)), "source unit 'bearing'"),
    ]:
        with pytest.raises(CouplingError, match=msg):
            check_connections([bad], ins, outs)


def test_evaluation_order_and_algebraic_loops():
    conns = [Connection("a.u", ("b.y",)), Connection("b.u", ("c.y",)), Connection("c.u", ("r.y",))]
    order = evaluation_order(
        ["a", "b", "c", "r"], conns, {"a": True, "b": True, "c": True, "r": False}
    )
    assert order == ["r", "c", "b", "a"]
    loop = [Connection("a.u", ("b.y",)), Connection("b.u", ("a.y",))]
    with pytest.raises(CosimError, match="algebraic loop between units a, b"):
        evaluation_order(["a", "b"], loop, {"a": True, "b": True})


def test_settings_are_validated_by_name():
    s = cosim_settings({"algorithm": "jacobi", "extrapolation": 1, "step": 1e-5, "order": ["r"]})
    assert (s.algorithm, s.extrapolation, s.step, s.order) == ("jacobi", 1, 1e-5, ("r",))
    d = CosimSettings().with_defaults(0.04)
    assert (d.step, d.max_step, d.min_step) == (1e-4, 4e-3, pytest.approx(4e-11))
    for raw, msg in [
        ({"algoritm": "x"}, "cosim.algoritm is not a setting"),
        ({"algorithm": "newton"}, "cosim.algorithm = 'newton' is not one of"),
        ({"extrapolation": 3}, r"cosim.extrapolation = 3 must be an integer in \[0, 2\]"),
        ({"rtol": 0.0}, "cosim.rtol = 0.0 must be > 0"),
        ({"step": -1.0}, "cosim.step"),
        ({"adaptive": "yes"}, "cosim.adaptive"),
        ({"order": "rotor"}, "cosim.order"),
        ({"backend": "gpu"}, "cosim.backend"),
        ({"events": "maybe"}, "cosim.events"),
        ({"unit_rtol": 1e-15}, "cosim.unit_rtol"),
        ({"min_step": 1.0, "max_step": 0.5}, "cosim.min_step must not exceed"),
        ({"iterations": 0}, "cosim.iterations"),
        ({"chatter_tol": 1e-8}, "cosim.chatter_tol = 1e-08 must be >= 1e-7"),
    ]:
        with pytest.raises(SettingsError, match=msg):
            cosim_settings(raw)


def test_unit_input_derivatives():
    rotor = make_unit("rotor", "jeffcott", mass=10.0, damping=0.0, stiffness=1e6,
                      eccentricity=0.0, speed=100.0)  # fmt: skip
    rotor.set_input("fx", 2.0)
    rotor.set_input_derivative("fx", 1, 10.0)
    rotor.set_input_derivative("fx", 2, 4.0)
    rotor.time = 1.0
    assert rotor.input_at("fx", 1.5) == pytest.approx(2.0 + 5.0 + 0.5)
    snap = rotor.get_state()
    assert rotor.state_from_bytes(rotor.state_to_bytes(snap))["du"] == {"fx": [10.0, 4.0]}
    rotor.set_input("fx", 3.0)  # a new value drops the derivatives
    assert rotor.input_at("fx", 9.0) == 3.0
    rotor.set_state(snap)
    assert rotor.input_at("fx", 1.5) == pytest.approx(7.5)
    with pytest.raises(ValueError, match="derivative order 3"):
        rotor.set_input_derivative("fx", 3, 1.0)
    with pytest.raises(KeyError, match="rotor.fz is not an input"):
        rotor.set_input_derivative("fz", 1, 1.0)
    with pytest.raises(ValueError, match="not finite"):
        rotor.set_input_derivative("fx", 1, math.nan)


def test_a_ramp_force_through_derivatives_matches_the_closed_form():
    # a free mass (no shaft, no damping) pushed by f = a + b t: x = a t^2/2m + b t^3/6m
    m, a, b = 2.0, 3.0, 40.0
    rotor = make_unit("rotor", "jeffcott", mass=m, damping=0.0, stiffness=1e-30,
                      eccentricity=0.0, speed=0.0)  # fmt: skip
    rotor.set_input("fx", a)
    rotor.set_input_derivative("fx", 1, b)
    rotor.do_step(0.0, 0.5)
    t = 0.5
    assert rotor.get_outputs()["x"] == pytest.approx(
        a * t**2 / (2 * m) + b * t**3 / (6 * m), rel=1e-9
    )


def test_rigid_stator_sustained_contact_outputs():
    st = make_unit("stator", "rigid", clearance=1e-4, friction=0.2, disc_radius=0.05, speed=100.0,
                   disc_mass=10.0, constraint_rate=0.0)  # fmt: skip
    # disc on the surface at +x, at rest, pushed outward by 50 N
    st.set_inputs({"x": 1e-4, "other_fx": 50.0, "contact_mode": 1})
    o = st.get_outputs()
    assert o["normal_force"] == pytest.approx(50.0)
    assert o["fx"] == pytest.approx(-50.0)
    assert o["fy"] == pytest.approx(-0.2 * 50.0)  # friction against the slip Rd w > 0 (along +y)
    assert o["slip"] == pytest.approx(5.0) and o["contact"] == 1.0
    st.set_input("contact_mode", 3)
    assert st.get_outputs()["contact"] == 2.0
    st.set_input("contact_mode", 7)
    with pytest.raises(ValueError, match="contact_mode = 7"):
        st.get_outputs()
    bare = make_unit("stator", "rigid", clearance=1e-4)
    bare.set_input("contact_mode", 1)
    with pytest.raises(ValueError, match="stator.disc_mass must be > 0"):
        bare.get_outputs()


def test_nearest_differences_match_impacts_by_time():
    import numpy as np

    from rubcosim.consistency import nearest_differences

    ref = np.array([1.0, 2.0, 2.5, 2.6, 4.0])
    got = nearest_differences(np.array([1.0 + 1e-9, 2.55, 4.0]), ref)
    assert got == pytest.approx([1e-9, 0.05, 0.0])
    assert nearest_differences(np.array([3.0]), np.array([1.0])) == pytest.approx([2.0])
    assert nearest_differences(np.zeros(0), ref).size == 0


def test_fmu_paths_build_only_what_is_missing(tmp_path, monkeypatch):
    from rubcosim.orchestrator.assembly import FMU_CACHE_ENV, default_fmu_dir, fmu_paths

    monkeypatch.setenv(FMU_CACHE_ENV, str(tmp_path / "cache"))
    assert default_fmu_dir().parent == tmp_path / "cache"
    paths = fmu_paths({"rotor": "jeffcott"}, tmp_path / "fmus")
    assert paths["rotor"].name == "RubcosimJeffcottRotor.fmu" and paths["rotor"].is_file()
    stamp = paths["rotor"].stat().st_mtime_ns
    assert fmu_paths({"rotor": "jeffcott"}, tmp_path / "fmus") == paths
    assert paths["rotor"].stat().st_mtime_ns == stamp  # not rebuilt


def test_fmu_builds_of_other_sources_unused_for_30_days_are_removed(tmp_path, monkeypatch):
    from rubcosim.orchestrator.assembly import FMU_CACHE_ENV, default_fmu_dir, fmu_paths

    monkeypatch.setenv(FMU_CACHE_ENV, str(tmp_path / "cache"))
    current = default_fmu_dir()
    forty_days_ago = time.time() - 40 * 86400.0
    names = ("0123456789ab", "ba9876543210", "mine")
    stale, recent, other = (tmp_path / "cache" / n for n in names)
    for folder in (current, stale, recent, other):
        folder.mkdir(parents=True, exist_ok=True)
    for folder in (current, stale, other):
        os.utime(folder, (forty_days_ago, forty_days_ago))
    paths = fmu_paths({"rotor": "jeffcott"}, None)
    assert paths["rotor"].parent == current and paths["rotor"].is_file()
    # this version's builds are marked as used; another version's unused for 40 days go;
    # one used recently and a folder not named by a digest stay
    assert current.stat().st_mtime > forty_days_ago + 30 * 86400.0
    assert not stale.exists() and recent.is_dir() and other.is_dir()
