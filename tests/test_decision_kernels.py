"""The contact and impact decisions written once in components/, against closed forms,
and the proof that the reference and the co-simulation call the same kernels."""

import math

import numpy as np
import pytest

from rubcosim.components.kernels import planar_newton, polynomial_at
from rubcosim.components.oscillator import barrier_gap, pressing, stop_impact
from rubcosim.components.stator import (
    MODE_FREE,
    MODE_SLIDE_NEG,
    MODE_SLIDE_POS,
    MODE_STICK,
    chattering_ended,
    friction_force,
    friction_limit,
    friction_reserve,
    penalty_normal,
    penalty_normal_force,
    reduced_mass,
    settle_mode,
    slip_mode,
)
from rubcosim.components.unit_odes import input_at
from rubcosim.orchestrator.extrapolation import evaluate, polynomial


def test_penalty_normal_is_kelvin_voigt():
    # 2 um into a 1e7 N/m spring closing at 0.01 m/s through a 100 N s/m damper
    assert penalty_normal(1.002e-3, 0.01, 1e-3, 1e7, 100.0) == pytest.approx(20.0 + 1.0)
    # a separating disc can make the damper pull
    assert penalty_normal(1.0001e-3, -0.1, 1e-3, 1e7, 100.0) == pytest.approx(1.0 - 10.0)
    fn, dist, nx, ny = penalty_normal_force(0.0, -1.002e-3, 0.0, -0.01, 1e-3, 1e7, 100.0)
    assert (fn, dist, nx, ny) == pytest.approx((21.0, 1.002e-3, 0.0, -1.0))


@pytest.mark.parametrize("n", [-5.0, 0.0, 40.0])
def test_friction_force_opposes_the_slip_with_coulomb_magnitude(n):
    mu = 0.15
    limit = mu * max(n, 0.0)
    assert friction_limit(mu, n) == limit
    assert friction_force(MODE_SLIDE_POS, mu, n, 7.0) == -limit
    assert friction_force(MODE_SLIDE_NEG, mu, n, 7.0) == limit
    assert friction_force(MODE_STICK, mu, n, 7.0) == 7.0
    assert friction_force(MODE_FREE, mu, n, 7.0) == 0.0
    assert friction_reserve(mu, n, -7.0) == limit - 7.0


def test_slip_mode_follows_the_sign_of_the_slip():
    assert slip_mode(1e-12) == MODE_SLIDE_POS
    assert slip_mode(-1e-12) == MODE_SLIDE_NEG
    assert slip_mode(0.0) == MODE_STICK  # no slip: the stateless penalty gives no friction


@pytest.mark.parametrize(
    ("slip", "threshold", "reserve", "hold", "current", "expected"),
    [
        # landing on the stator: fast slip slides with its sign
        (0.3, 1e-6, 5.0, 2.0, MODE_FREE, MODE_SLIDE_POS),
        (-0.3, 1e-6, 5.0, 2.0, MODE_FREE, MODE_SLIDE_NEG),
        # no slip: sticks if friction holds it, else slides against the holding force
        (1e-9, 1e-6, 5.0, 2.0, MODE_FREE, MODE_STICK),
        (1e-9, 1e-6, -1.0, 2.0, MODE_FREE, MODE_SLIDE_NEG),
        (1e-9, 1e-6, -1.0, -2.0, MODE_FREE, MODE_SLIDE_POS),
        # slip reversal event: sticks if friction holds, else slides the other way ...
        (0.0, math.inf, 5.0, 2.0, MODE_SLIDE_POS, MODE_STICK),
        (0.0, math.inf, -1.0, 2.0, MODE_SLIDE_POS, MODE_SLIDE_NEG),
        # ... but never back the way it came (the slip event just ruled that out)
        (0.0, math.inf, -1.0, -2.0, MODE_SLIDE_POS, MODE_STICK),
        # friction reserve exhausted while sticking: slide against the holding force
        (0.0, math.inf, -1e-9, 2.0, MODE_STICK, MODE_SLIDE_NEG),
        (0.0, math.inf, 0.0, -2.0, MODE_STICK, MODE_SLIDE_POS),
    ],
)
def test_settle_mode(slip, threshold, reserve, hold, current, expected):
    assert settle_mode(slip, threshold, reserve, hold, current) == expected


def test_chattering_ends_after_the_closed_form_number_of_impacts():
    # rebounds r^k v0 of a restitution r: the first below v_chat is k = ceil(log(v_chat/v0)/log r)
    r, v0, v_chat = 0.8, 1e-2, 3.8e-9
    k, v = 0, v0
    while True:
        v *= r
        k += 1
        if chattering_ended(v, v_chat, math.inf, 0.0):
            break
    assert k == math.ceil(math.log(v_chat / v0) / math.log(r))
    # a flight too short to resolve ends it whatever the rebound
    assert chattering_ended(1.0, v_chat, 1e-12, 1e-11)
    assert not chattering_ended(1.0, v_chat, 1e-10, 1e-11)


def test_stop_impact_obeys_newton_and_sticks_only_when_pressed():
    v_plus, stuck = stop_impact(2.0, 0.8, 1e-9, 1, -3.0)
    assert (v_plus, stuck) == (-1.6, False)
    assert v_plus**2 == pytest.approx(0.8**2 * 2.0**2)  # kinetic energy times R^2
    assert stop_impact(1e-12, 0.8, 1e-9, 1, 3.0) == (0.0, True)  # pushed into +D
    assert stop_impact(1e-12, 0.8, 1e-9, 1, -3.0) == (0.0, False)  # pulled away from +D
    assert stop_impact(-1e-12, 0.8, 1e-9, -1, -3.0) == (0.0, True)  # pushed into -D
    assert pressing(-1, -3.0) == 3.0
    assert barrier_gap(0.25, 1.0, 1) == 0.75
    assert barrier_gap(-0.25, 1.0, -1) == 0.75


def test_planar_newton_conserves_energy_of_a_spring_mass():
    # x'' = -k/m x with a classical RK4 step built on the kernel: energy drift O(h^4)
    m, k, h = 2.0, 50.0, 1e-3

    def f(y):
        dy = np.zeros(4)
        planar_newton(y, 0, -k * y[0], -k * y[1], m, dy)
        return dy

    y = np.array([0.01, 0.0, 0.0, 0.05])
    energy = 0.5 * m * (y[2] ** 2 + y[3] ** 2) + 0.5 * k * (y[0] ** 2 + y[1] ** 2)
    for _ in range(2000):
        k1 = f(y)
        k2 = f(y + 0.5 * h * k1)
        k3 = f(y + 0.5 * h * k2)
        k4 = f(y + h * k3)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    after = 0.5 * m * (y[2] ** 2 + y[3] ** 2) + 0.5 * k * (y[0] ** 2 + y[1] ** 2)
    assert after == pytest.approx(energy, rel=1e-9)
    dy = np.zeros(8)
    planar_newton(np.arange(8.0), 4, 3.0, -6.0, 3.0, dy)
    assert list(dy) == [0.0, 0.0, 0.0, 0.0, 6.0, 7.0, 1.0, -2.0]


def test_every_input_polynomial_is_the_same_kernel():
    # the quadratic through three points, evaluated by each user, against numpy
    pts = [(0.0, 1.0), (0.5, 2.0), (1.5, 0.5)]
    coeffs = np.polyfit([p[0] for p in pts], [p[1] for p in pts], 2)
    value, d1, d2 = polynomial(pts, 1.5)
    for s in (0.0, 0.1, 0.7):
        expected = np.polyval(coeffs, 1.5 + s)
        assert polynomial_at(value, d1, d2, s) == pytest.approx(expected, rel=1e-12)
        assert evaluate(value, d1, d2, s) == polynomial_at(value, d1, d2, s)
        assert input_at(np.array([[value, d1, d2]]), 0, s) == polynomial_at(value, d1, d2, s)


def test_reduced_mass():
    assert reduced_mass(10.0, 5.0) == pytest.approx(10.0 / 3.0)
    assert reduced_mass(10.0, 1e30) == pytest.approx(10.0)  # a casing of infinite mass
    assert reduced_mass(4.0, 4.0) == 2.0
