"""Exact steps of the linear rotor units (components/linear_propagation.py), checked
against scipy's matrix exponential, the closed-form unbalance response of a Jeffcott
rotor (steady whirl, and the secular growth at undamped resonance) and DOP853 steps."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from rubcosim.components.linear_propagation import affine_model, exact_step, expm
from rubcosim.components.modal_propagation import ModalPropagator
from rubcosim.components.propagator_cache import PropagatorCache
from rubcosim.components.rotor import free_whirl
from rubcosim.components.rotor_unit import JeffcottRotorUnit
from rubcosim.components.stepping import step_ode
from rubcosim.components.unit_odes import JEFFCOTT, TWO_MASS, unit_rhs
from rubcosim.orchestrator.settings import SettingsError, cosim_settings

M, K, E = 10.0, 1e6, 1e-4
WN = math.sqrt(K / M)
SCALES4 = np.array([E, E, E * WN, E * WN])


@pytest.mark.parametrize("norm", [1e-3, 0.2, 1.5, 4.0, 60.0])
def test_expm_agrees_with_scipy_at_every_pade_degree_and_with_squaring(norm):
    rng = np.random.default_rng(int(norm * 1000))
    A = rng.normal(size=(9, 9))
    A *= norm / np.abs(A).sum(axis=0).max()
    ref = scipy.linalg.expm(A)
    assert np.max(np.abs(expm(A) - ref)) <= 1e-13 * np.max(np.abs(ref))


@pytest.mark.parametrize("kind, n, n_in", [(JEFFCOTT, 4, 2), (TWO_MASS, 8, 4)])
def test_affine_model_reproduces_the_units_right_hand_side(kind, n, n_in):
    w = 1.2 * WN
    p = np.array([M, 40.0, K, E, w, 9.81, 25.0, 2.0, 15.0][: 6 if kind == JEFFCOTT else 9])
    A, Bu, a, b, c = affine_model(kind, p, n, n_in, w)
    rng = np.random.default_rng(3)
    for _ in range(5):
        y = rng.normal(size=n) * np.tile(SCALES4, n // 4)
        u = np.zeros((n_in, 3))
        u[:, 0] = rng.normal(size=n_in) * 50.0
        t = rng.uniform(0.0, 1.0)
        dy = np.empty(n)
        unit_rhs(kind, t, y, p, u, t, dy)
        model = A @ y + Bu @ u[:, 0] + a + b * math.cos(w * t) + c * math.sin(w * t)
        assert np.allclose(model, dy, rtol=1e-12, atol=1e-12 * np.abs(dy).max())


def _whirl(t: float, amp: float, phase: float, w: float) -> np.ndarray:
    th = w * t - phase
    return np.array([amp * math.cos(th), amp * math.sin(th), -amp * w * math.sin(th),
                     amp * w * math.cos(th)])  # fmt: skip


@pytest.mark.parametrize("h", [1e-6, 1e-4, 3e-3, 0.2])
@pytest.mark.parametrize("speed_ratio", [0.5, 1.2, 3.0])
def test_exact_step_follows_the_closed_form_steady_whirl(h, speed_ratio):
    w = speed_ratio * WN
    c = 2.0 * 0.05 * M * WN
    amp, phase = free_whirl(M, c, K, E, w)
    model = affine_model(JEFFCOTT, np.array([M, c, K, E, w, 0.0]), 4, 2, w)
    t0 = 0.0371
    y1 = exact_step(t0, h, _whirl(t0, amp, phase, w), model, w, np.zeros((2, 3)))
    err = np.abs(y1 - _whirl(t0 + h, amp, phase, w)) / np.array([amp, amp, amp * w, amp * w])
    assert err.max() < 1e-12


def test_exact_step_grows_the_undamped_resonance_linearly():
    # x'' + wn^2 x = e wn^2 cos(wn t): x = (e wn / 2) t sin(wn t), y = -(e wn / 2) t cos(wn t)
    # + (e / 2) sin(wn t): a rotor that no DOP853 tolerance keeps bounded-error for long
    w = WN
    model = affine_model(JEFFCOTT, np.array([M, 0.0, K, E, w, 0.0]), 4, 2, w)

    def exact(t):
        s, co = math.sin(w * t), math.cos(w * t)
        x = 0.5 * E * w * t * s
        y = -0.5 * E * w * t * co + 0.5 * E * s
        vx = 0.5 * E * w * (s + w * t * co)
        vy = 0.5 * E * w * (-co + w * t * s) + 0.5 * E * w * co
        return np.array([x, y, vx, vy])

    y, t = exact(0.0), 0.0
    for h in (0.013, 0.3, 1.1, 0.0007):
        y = exact_step(t, h, y, model, w, np.zeros((2, 3)))
        t += h
    scale = np.abs(exact(t)).max()
    assert np.abs(y - exact(t)).max() < 1e-11 * scale


def test_exact_step_agrees_with_dop853_under_polynomial_inputs_and_gravity():
    rng = np.random.default_rng(7)
    w = 1.3 * WN
    p = np.array([M, 30.0, K, E, w, 9.81, 10.0, 2.0, 5.0])
    model = affine_model(TWO_MASS, p, 8, 4, w)
    scales = np.tile(SCALES4, 2)
    for h in (1e-5, 4e-4):
        y0 = rng.normal(size=8) * scales
        u = rng.normal(size=(4, 3)) * np.array([20.0, 20.0 * WN, 20.0 * WN**2])
        y_exact = exact_step(0.21, h, y0, model, w, u)
        y_rk, _ = step_ode(TWO_MASS, 0.21, 0.21 + h, y0.copy(), 0.0, p, u, 1e-13, 1e-22)
        assert np.max(np.abs(y_exact - y_rk) / scales) < 1e-12


@pytest.mark.parametrize("damping", [100.0, 2.0 * math.sqrt(K * M)])
def test_rotor_unit_in_plain_numpy_takes_each_path_and_agrees_with_the_compiled_step(
    monkeypatch, damping
):
    # an FMU's unit (numba off): steps of a new length in modal coordinates (or, at
    # critical damping, the exponential), repeated lengths from the cached propagators;
    # all of them the compiled exact step's to round-off
    from rubcosim.components import rotor_unit

    compiled = JeffcottRotorUnit.example(eccentricity=E, damping=damping, mass=M, stiffness=K)
    plain = JeffcottRotorUnit.example(eccentricity=E, damping=damping, mass=M, stiffness=K)
    t = 0.0
    for k, h in enumerate((3e-4, 2e-4, 2e-4, 2e-4, 5e-3, 1e-5, 1e-5)):
        for unit in (compiled, plain):
            unit.set_input_polynomial("fx", 5.0 + k, 300.0, -2e4)
            unit.set_input_polynomial("fy", -3.0, 100.0 * k, 0.0)
        compiled.do_step(t, h)
        monkeypatch.setattr(rotor_unit, "USE_NUMBA", False)
        plain.do_step(t, h)
        monkeypatch.setattr(rotor_unit, "USE_NUMBA", True)
        t += h
        a, b = compiled.state["y"], plain.state["y"]
        assert np.max(np.abs(a - b) / SCALES4) < 1e-11
    assert (plain._modal() is None) == (damping > 1000.0)  # critical: no eigenvector basis
    assert plain._propagators().computed == 2  # 2e-4 and 1e-5, each once


def test_rotor_unit_steps_exactly_by_default_and_dop853_on_request():
    exact = JeffcottRotorUnit.example(eccentricity=E, damping=100.0)
    rk = JeffcottRotorUnit.example(eccentricity=E, damping=100.0, integrator="dop853")
    assert exact.params["integrator"] == "exact"
    for unit in (exact, rk):
        unit.set_input_polynomial("fx", 5.0, 300.0, 0.0)
        unit.do_step(0.0, 2e-3)
    a, b = exact.get_outputs(), rk.get_outputs()
    assert abs(a["x"] - b["x"]) < 1e-8 * abs(a["x"])  # DOP853's rtol 1e-10, not better
    with pytest.raises(Exception, match="integrator"):
        JeffcottRotorUnit.example(integrator="rk4")


def _whirl_or_resonance(speed_ratio):
    """Spin speed, affine model and closed-form motion of a Jeffcott rotor: the steady
    whirl at 5 % damping, or, at ``speed_ratio`` 1, the undamped resonance from rest."""
    w = speed_ratio * WN
    c = 0.0 if speed_ratio == 1.0 else 2.0 * 0.05 * M * WN  # undamped at resonance
    model = affine_model(JEFFCOTT, np.array([M, c, K, E, w, 0.0]), 4, 2, w)
    if c:
        amp, phase = free_whirl(M, c, K, E, w)
        return w, model, lambda t: _whirl(t, amp, phase, w)

    def exact(t):  # x'' + wn^2 x = e wn^2 cos(wn t) from rest at the origin
        s, co = math.sin(w * t), math.cos(w * t)
        return 0.5 * E * np.array([w * t * s, -w * t * co + s, w * (s + w * t * co),
                                   w * (-co + w * t * s) + w * co])  # fmt: skip

    return w, model, exact


@pytest.mark.parametrize("speed_ratio", [0.5, 1.0, 3.0])
def test_cached_propagators_follow_the_closed_form_whirl_and_resonance(speed_ratio):
    # the FMU's path: E, P1..P3, Wc, Ws from one 6n x 6n exponential per step size
    w, model, exact = _whirl_or_resonance(speed_ratio)
    cache = PropagatorCache(model, w)
    t, y = 0.0371, exact(0.0371)
    for h in (3e-4, 3e-4, 3e-4, 0.02, 0.02, 3e-4):
        y = cache.step(t, h, y, np.zeros((2, 3)))
        t += h
    scale = np.abs(exact(t)).max()
    assert np.abs(y - exact(t)).max() < 1e-12 * scale
    assert cache.computed == 2  # each step size's propagators once


def test_cached_propagators_agree_with_the_per_step_exponential_under_inputs():
    rng = np.random.default_rng(11)
    w = 1.3 * WN
    p = np.array([M, 30.0, K, E, w, 9.81, 10.0, 2.0, 5.0])
    model = affine_model(TWO_MASS, p, 8, 4, w)
    cache = PropagatorCache(model, w, size=2)
    scales = np.tile(SCALES4, 2)
    for h in (1e-5, 4e-4, 0.03, 1e-5, 4e-4):
        for _ in range(3):
            y0 = rng.normal(size=8) * scales
            u = rng.normal(size=(4, 3)) * np.array([20.0, 20.0 * WN, 20.0 * WN**2])
            t0 = rng.uniform(0.0, 2.0)
            ref = exact_step(t0, h, y0, model, w, u)
            assert np.max(np.abs(cache.step(t0, h, y0, u) - ref) / scales) < 1e-12
    # three step sizes kept at most two at a time: 1e-5 and 4e-4 were computed again
    assert cache.computed == 5 and len(cache.kept) == 2


def test_bad_unit_integrator_setting_is_named():
    with pytest.raises(SettingsError, match="cosim.unit_integrator"):
        cosim_settings({"unit_integrator": "euler"})


@pytest.mark.parametrize("speed_ratio", [0.5, 1.0, 3.0])
def test_modal_steps_follow_the_closed_form_whirl_and_resonance(speed_ratio):
    # an FMU's step of a new length: modal coordinates, steps short and long (|lambda h|
    # from 3e-4, the series, to 95, the closed forms), the undamped resonance included
    w, model, exact = _whirl_or_resonance(speed_ratio)
    modal = ModalPropagator.build(model, w)
    assert modal is not None and len(modal.lam) == 2  # one mode per conjugate pair
    t, y = 0.0371, exact(0.0371)
    for h in (1e-6, 3e-4, 2.9e-4, 0.02, 0.3, 1e-5):
        y = modal.step(t, h, y, np.zeros((2, 3)))
        t += h
    scale = np.abs(exact(t)).max()
    assert np.abs(y - exact(t)).max() < 1e-12 * scale


def test_modal_steps_agree_with_the_per_step_exponential_under_inputs():
    rng = np.random.default_rng(5)
    w = 1.3 * WN
    p = np.array([M, 30.0, K, E, w, 9.81, 10.0, 2.0, 5.0])
    model = affine_model(TWO_MASS, p, 8, 4, w)
    modal = ModalPropagator.build(model, w)
    assert modal is not None
    scales = np.tile(SCALES4, 2)
    for h in (1e-7, 1e-5, 4e-4, 0.03, 1.0):
        for _ in range(3):
            y0 = rng.normal(size=8) * scales
            u = rng.normal(size=(4, 3)) * np.array([20.0, 20.0 * WN, 20.0 * WN**2])
            t0 = rng.uniform(0.0, 2.0)
            ref = exact_step(t0, h, y0, model, w, u)
            err = np.max(np.abs(modal.step(t0, h, y0, u) - ref) / scales)
            # round-off: the eigendecomposition's backward error (LAPACK's, about 130 eps
            # of the balanced |A| here) carried over h |lambda|max (up to 770); it depends
            # on the CPU's LAPACK kernels: 1.5e-11 of the state measured on an AMD EPYC
            # (OpenBLAS 0.3.31), a third of that where this test was first written
            assert err < 5e-11 * max(1.0, np.max(np.abs(ref) / scales))


@pytest.mark.parametrize("damping, stiffness", [(2.0 * math.sqrt(K * M), K), (0.0, 0.0)])
def test_modal_coordinates_are_refused_where_the_matrix_is_defective(damping, stiffness):
    # critical damping (a double eigenvalue with one eigenvector) and a free rigid disc
    # (x'' = 0): no eigenvector basis, so the unit keeps the matrix exponential
    w = 0.7 * WN
    model = affine_model(JEFFCOTT, np.array([M, damping, stiffness, E, w, 0.0]), 4, 2, w)
    assert ModalPropagator.build(model, w) is None


def test_balancing_is_finite_and_the_same_in_the_compiled_kernel_and_an_fmus_plain_copy(
    monkeypatch,
):
    # random matrices whose entries span 24 decades, and two whose rows and columns are
    # (nearly) empty: the plain copy used to scale every index at once, which
    # overflowed on such a matrix (seen in the FMU fuzz of the two-mass rotor)
    from rubcosim.components import linear_propagation as lp

    rng = np.random.default_rng(1)
    cases = [rng.standard_normal((9, 9)) * 10.0 ** rng.uniform(-12, 12, (9, 9)) for _ in range(50)]
    m1 = np.zeros((4, 4))
    m1[0, 1], m1[1, 0], m1[2, 3], m1[3, 2] = 1e-300, 1e300, 1.0, -1e6
    m2 = np.eye(5)
    m2[0, :] = 0.0
    m2[0, 1], m2[1, 0] = 1e-310, 1e308
    for m in [*cases, m1, m2]:
        compiled = lp.balance(m)
        with monkeypatch.context() as patch:
            patch.setattr(lp, "USE_NUMBA", False)
            with np.errstate(all="raise"):
                plain = lp.balance.py_func(m)
        assert np.all(np.isfinite(compiled)) and np.all(compiled > 0.0)
        assert np.array_equal(compiled, plain)
        assert np.all(np.abs(np.log2(compiled)) <= 300.0)
