"""Component kernels against independent figures (published values, closed forms)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rubcosim.components.bearing import (
    capone_force,
    linear_bearing_force,
    oilfilm_force,
    oilfilm_sigma,
)
from rubcosim.components.controller import SHAPE_SINE, delay_at, feedback_force
from rubcosim.components.oscillator import elastic_stop_force, free_acceleration, impact_velocity
from rubcosim.components.rotor import free_whirl, jeffcott_force, shaft_force, unbalance_force
from rubcosim.components.stator import (
    constraint_normal_force,
    contact_force_components,
    contact_geometry,
    damping_from_restitution,
    penalty_contact_force,
    penalty_normal_force,
    rigid_impact,
    rub_onset_speed_ratios,
    slip_speed,
    sticking_friction,
)


def test_rub_onset_speeds_match_published_values():
    lo, hi = rub_onset_speed_ratios(0.05, 0.5)
    assert lo == pytest.approx(0.8206, abs=5e-5)
    assert hi == pytest.approx(1.4071, abs=5e-5)


def test_rub_onset_none_when_whirl_never_reaches_stator():
    assert rub_onset_speed_ratios(0.5, 0.5) == ()
    # e > d: the whirl reaches the stator once and for all at high speed
    assert len(rub_onset_speed_ratios(0.05, 1.5)) == 1


def test_free_whirl_closed_form():
    amp, phase = free_whirl(2.0, 0.0, 800.0, 1e-3, 20.0)  # at resonance without damping
    assert math.isinf(amp)
    assert phase == pytest.approx(math.pi / 2)
    amp, phase = free_whirl(1.0, 0.0, 1.0, 1e-3, 1e3)  # far above: A -> e, phase -> pi
    assert amp == pytest.approx(1e-3, rel=1e-5)
    assert phase == pytest.approx(math.pi)


def test_jeffcott_and_shaft_forces():
    fx, fy = jeffcott_force(0.0, 1e-3, 0.0, 0.0, 0.1, 2.0, 3.0, 100.0, 0.0, 0.0, 9.81)
    assert fx == pytest.approx(-0.1)
    assert fy == pytest.approx(-0.3 - 2.0 * 9.81)
    ux, uy = unbalance_force(math.pi / 2 / 10.0, 1.0, 1e-3, 10.0)
    assert ux == pytest.approx(0.0, abs=1e-15)
    assert uy == pytest.approx(0.1)
    sx, sy = shaft_force(np.array([1.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0]), 0, 4, 10.0, 0.0)
    assert (sx, sy) == (-5.0, 0.0)


def test_frictionless_impact_keeps_tangential_and_scales_normal():
    n = np.array([0.6, 0.8])
    t = np.array([-0.8, 0.6])
    v = 2.0 * n + 0.7 * t
    vx, vy = rigid_impact(v[0], v[1], n[0], n[1], 0.6, 0.0, 0.0, 0.0)
    assert vx * n[0] + vy * n[1] == pytest.approx(-1.2)
    assert vx * t[0] + vy * t[1] == pytest.approx(0.7)


def test_receding_disc_is_not_changed():
    assert rigid_impact(-1.0, 0.0, 1.0, 0.0, 0.5, 0.3, 0.1, 100.0) == (-1.0, 0.0)


def test_friction_impulse_opposes_slip_and_can_stop_it():
    # slip positive (spin): the tangential speed drops by mu (1 + r) vn
    vx, vy = rigid_impact(1.0, 0.0, 1.0, 0.0, 0.5, 0.2, 0.05, 100.0)
    assert vy == pytest.approx(-0.2 * 1.5 * 1.0)
    # a large impulse stops the slip exactly (vs = vt + Rd w = 0), never reverses it
    vx, vy = rigid_impact(1.0, 0.01, 1.0, 0.0, 0.5, 0.9, 0.0, 0.0)
    assert vy == pytest.approx(0.0)


@settings(max_examples=300, deadline=None)
@given(
    vx=st.floats(-10, 10),
    vy=st.floats(-10, 10),
    angle=st.floats(0, 2 * math.pi),
    r=st.floats(0, 1),
    mu=st.floats(0, 2),
    rd_w=st.floats(-5, 5),
)
def test_impact_never_creates_kinetic_energy(vx, vy, angle, r, mu, rd_w):
    nx, ny = math.cos(angle), math.sin(angle)
    wx, wy = rigid_impact(vx, vy, nx, ny, r, mu, rd_w, 1.0)
    # energy of the motion relative to the contact point (normal speed, slip speed)
    vs0 = slip_speed(vx, vy, nx, ny, rd_w, 1.0)
    vs1 = slip_speed(wx, wy, nx, ny, rd_w, 1.0)
    vn0 = vx * nx + vy * ny
    vn1 = wx * nx + wy * ny
    assert vn1**2 + vs1**2 <= vn0**2 + vs0**2 + 1e-12 * (1 + vx * vx + vy * vy)
    # without spin the plain kinetic energy of the disc never grows
    wx0, wy0 = rigid_impact(vx, vy, nx, ny, r, mu, 0.0, 0.0)
    assert wx0**2 + wy0**2 <= vx * vx + vy * vy + 1e-12 * (1 + vx * vx + vy * vy)


def test_penalty_force_is_chu_zhang_form_for_positive_slip():
    kc, d, mu = 5e6, 1e-4, 0.2
    rx, ry = 0.9e-4, 0.7e-4
    fx, fy, fn = penalty_contact_force(rx, ry, 0.0, 0.0, d, kc, 0.0, mu, 0.05, 300.0)
    e = math.hypot(rx, ry)
    factor = -kc * (1 - d / e)
    assert fx == pytest.approx(factor * (rx - mu * ry), rel=1e-12)
    assert fy == pytest.approx(factor * (mu * rx + ry), rel=1e-12)
    assert fn == pytest.approx(kc * (e - d))
    assert penalty_contact_force(0.5e-4, 0.0, 1.0, 1.0, d, kc, 1.0, mu, 0.0, 0.0) == (0.0, 0.0, 0.0)


def test_penalty_friction_follows_only_the_compressive_normal_force():
    # separating fast, the damper makes the normal force pull: no friction then (a
    # Coulomb force mu Fn would push the disc along its slip)
    kc, d, mu, cc = 5e6, 1e-4, 0.2, 2e4
    fx, fy, fn = penalty_contact_force(1.001e-4, 0.0, -1.0, 0.5, d, kc, cc, mu, 0.05, 300.0)
    assert fn < 0.0 and fy == 0.0 and fx == pytest.approx(-fn)


def test_contact_geometry_at_centre_is_safe():
    assert contact_geometry(0.0, 0.0) == (0.0, 1.0, 0.0)


def test_constraint_normal_force_balances_centripetal_load():
    # disc sliding on r = d at tangential speed vt, no other force: N = m vt^2 / d
    assert constraint_normal_force(
        0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.5, 0.5, 3.0, 10.0
    ) == pytest.approx(24.0)


@pytest.mark.parametrize("r", [0.0, 0.3, 0.8, 1.0])
def test_damping_from_restitution(r):
    kc, m = 1e6, 2.0
    cc = damping_from_restitution(r, kc, m)
    zeta = cc / (2 * math.sqrt(kc * m))
    if r == 0.0:
        assert zeta == pytest.approx(1.0)
    elif r == 1.0:
        assert cc == 0.0
    else:
        assert math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2)) == pytest.approx(r, rel=1e-12)


@pytest.mark.parametrize("eps", [0.1, 0.3, 0.5, 0.7, 0.9])
def test_capone_matches_ocvirk_static_journal(eps):
    fx, fy = capone_force(eps, 0.0, 0.0, 0.0)
    assert fx == pytest.approx(-4 * eps**2 / (1 - eps**2) ** 2, rel=1e-12)
    assert fy == pytest.approx(math.pi * eps / (1 - eps**2) ** 1.5, rel=1e-12)


@pytest.mark.parametrize("x,y", [(0.3, 0.0), (0.1, -0.5), (-0.6, 0.2)])
def test_capone_half_speed_whirl_carries_no_load(x, y):
    fx, fy = capone_force(x, y, -y / 2, x / 2)
    assert abs(fx) < 1e-12 and abs(fy) < 1e-12


def test_capone_outside_clearance_is_nan():
    assert all(math.isnan(f) for f in capone_force(1.0, 0.1, 0.0, 0.0))


def test_oilfilm_dimensional_scaling():
    sigma = oilfilm_sigma(0.02, 300.0, 0.025, 0.02, 1e-4)
    assert sigma == pytest.approx(0.02 * 300 * 0.025 * 0.02 * 250**2 * 0.4**2)
    fx, fy = oilfilm_force(0.5e-4, 0.0, 0.0, 0.0, 300.0, 1e-4, sigma)
    ref = capone_force(0.5, 0.0, 0.0, 0.0)
    assert (fx, fy) == pytest.approx((sigma * ref[0], sigma * ref[1]))
    assert linear_bearing_force(1.0, 2.0, 3.0, 4.0, 10.0, 1.0) == (-13.0, -24.0)


def test_controller_kernels():
    assert delay_at(0.0, 0.1, 0.01, 5.0, SHAPE_SINE, 0) == pytest.approx(0.1)
    assert delay_at(math.pi / 10, 0.1, 0.01, 5.0, SHAPE_SINE, 0) == pytest.approx(0.11)
    assert feedback_force(2.0, 1.0, 1.0) == 0.0
    assert feedback_force(2.0, 1.0, 1.5) == pytest.approx(1.0)


def test_oscillator_kernels():
    assert free_acceleration(0.0, 1.0, 2.0, 3.0, 0.5, 1.0, 4.0, 1.0) == pytest.approx(4 - 1 - 3 - 1)
    assert impact_velocity(2.0, 0.7) == pytest.approx(-1.4)
    assert elastic_stop_force(1.5, 3, 1.0, 10.0) == pytest.approx(-5.0)
    assert elastic_stop_force(-1.5, 3, 1.0, 10.0) == 0.0
    assert elastic_stop_force(-1.5, 4, 1.0, 10.0) == pytest.approx(5.0)


def test_sticking_friction_holds_slip_constant():
    # fixed stator: the friction cancels the tangential load and the
    # centripetal correction vt vn / dist
    assert sticking_friction(3.0, 0.0, 0.0, 0.0, 1.0, 2.0, math.inf) == pytest.approx(-3.0)
    assert sticking_friction(0.0, 0.0, 2.0, 0.5, 1.0, 2.0, math.inf) == pytest.approx(2.0)
    # casing of mass ms: relative tangential acceleration zero
    m, ms, fd, fs = 2.0, 3.0, 1.5, -0.5
    ft = sticking_friction(fd, fs, 0.0, 0.0, 1.0, m, ms)
    assert (fd + ft) / m - (fs - ft) / ms == pytest.approx(0.0, abs=1e-15)


def test_penalty_normal_force_and_components():
    fn, dist, nx, ny = penalty_normal_force(3e-4, 4e-4, 1.0, 0.0, 4e-4, 1e6, 10.0)
    assert dist == pytest.approx(5e-4)
    assert (nx, ny) == pytest.approx((0.6, 0.8))
    assert fn == pytest.approx(1e6 * 1e-4 + 10.0 * 0.6)
    fx, fy = contact_force_components(2.0, 1.0, 0.6, 0.8)
    assert (fx, fy) == pytest.approx((-2.0 * 0.6 - 1.0 * 0.8, -2.0 * 0.8 + 1.0 * 0.6))


def test_two_mass_forces_obey_action_and_reaction():
    from rubcosim.components.rotor import journal_force, two_mass_disc_force

    state = np.array([2e-5, -1e-5, 0.01, 0.02, 5e-6, 3e-6, -0.004, 0.001])
    # with no unbalance, ground damping or gravity only the shaft acts: equal and opposite
    dx, dy = two_mass_disc_force(0.3, state, 0, 4, 10.0, 0.0, 1e6, 50.0, 0.0, 300.0, 0.0)
    jx, jy = journal_force(state, 0, 4, 1e6, 50.0, 2.0, 0.0, 0.0)
    assert (dx + jx, dy + jy) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert dx == pytest.approx(-1e6 * 1.5e-5 - 50.0 * 0.014)
    # ground damping and gravity on the journal
    gx, gy = journal_force(state, 0, 4, 1e6, 50.0, 2.0, 30.0, 9.81)
    assert (gx - jx, gy - jy) == pytest.approx((30.0 * 0.004, -30.0 * 0.001 - 2.0 * 9.81))


def test_hypot_is_within_two_ulps_of_the_exact_value_and_the_same_compiled_and_interpreted():
    # kernels.hypot against the exact value (decimal arithmetic) at every scale, and its
    # compiled form (the engines) against its interpreted one (inside an FMU): the same
    # bits, special values included
    import decimal

    import numba

    from rubcosim.components.kernels import hypot

    @numba.njit
    def compiled(a, b, out):
        for i in range(a.shape[0]):
            out[i] = hypot(a[i], b[i])

    rng = np.random.default_rng(7)
    scales = 10.0 ** rng.uniform(-310, 308, 200_000)
    with np.errstate(over="ignore"):  # some products overflow to inf: inputs too
        a = rng.normal(size=scales.size) * scales
        b = a * rng.choice([1.0, 0.3, 1e-3, 1e-9, 1e-20, 0.0, 1e4], scales.size)
        b *= rng.normal(size=scales.size)
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, 1.7e308, 3.0])
    a = np.concatenate([a, np.repeat(special, special.size)])
    b = np.concatenate([b, np.tile(special, special.size)])
    ours = np.empty_like(a)
    compiled(a, b, ours)
    interpreted = np.array([hypot.py_func(float(x), float(y)) for x, y in zip(a, b, strict=True)])
    same = (ours == interpreted) | (np.isnan(ours) & np.isnan(interpreted))
    assert same.all(), (a[~same][:3], b[~same][:3])
    worst = 0.0
    with decimal.localcontext() as ctx:
        ctx.prec = 60
        for i in range(0, 200_000, 23):
            if math.isfinite(ours[i]) and ours[i] > 0.0:
                x, y = decimal.Decimal(float(a[i])), decimal.Decimal(float(b[i]))
                exact = float((x * x + y * y).sqrt())
                worst = max(worst, abs(ours[i] - exact) / math.ulp(exact))
    assert worst <= 2.0, worst
    assert hypot(3.0, 4.0) == 5.0 and hypot(-5e-320, 0.0) == 5e-320
    assert hypot(0.0, -0.0) == 0.0 and math.isinf(hypot(-1.7e308, 1.7e308))  # beyond range
    assert hypot(-1e308, 1e308) == pytest.approx(math.sqrt(2.0) * 1e308, rel=1e-15)
    assert math.isinf(hypot(np.inf, np.nan)) and math.isinf(hypot(np.nan, -np.inf))
    assert math.isnan(hypot(np.nan, 1.0)) and math.isnan(hypot(1e-320, np.nan))
    assert hypot(3e300, 4e300) == pytest.approx(5e300, rel=1e-15)
    assert hypot(3e-300, 4e-300) == pytest.approx(5e-300, rel=1e-15)
