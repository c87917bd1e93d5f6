"""The monolithic reference against independent figures (closed forms, published values)."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rubcosim.reference import build_system, make_unit, simulate
from rubcosim.reference.core import STATUS_EVENT_LIMIT
from rubcosim.reference.system import MODE_FREE, MODE_STICK, MODE_STUCK_UPPER

M, K = 10.0, 1.0e6
WN = math.sqrt(K / M)
Z = 0.05
D = 1.0e-4


def rotor(s, rho=0.5, z=Z, **extra):
    params = dict(mass=M, damping=2 * z * M * WN, stiffness=K, eccentricity=rho * D, speed=s * WN)
    params.update(extra)
    return make_unit("rotor", "jeffcott", params)


def steady_start(s, rho=0.5, z=Z):
    """Initial state on the steady unbalance whirl (independent closed form)."""
    amp = rho * D * s * s / math.sqrt((1 - s * s) ** 2 + (2 * z * s) ** 2)
    phase = math.atan2(2 * z * s, 1 - s * s)
    w = s * WN
    return (
        dict(
            x0=amp * math.cos(-phase),
            y0=amp * math.sin(-phase),
            vx0=-amp * w * math.sin(-phase),
            vy0=amp * w * math.cos(-phase),
        ),
        amp,
        phase,
    )


@pytest.mark.parametrize("engine", ["fast", "accurate"])
@pytest.mark.parametrize("s", [0.5, 1.0, 2.5])
def test_free_whirl_matches_closed_form(engine, s):
    start, amp, phase = steady_start(s)
    system = build_system({"rotor": rotor(s, **start)})
    w = s * WN
    t_end = 10 * 2 * math.pi / w
    res = simulate(system, t_end, output_step=t_end / 400, engine=engine, rtol=1e-12)
    assert res.ok
    t = res.t
    err_x = np.max(np.abs(res.output("rotor.x") - amp * np.cos(w * t - phase)))
    err_y = np.max(np.abs(res.output("rotor.y") - amp * np.sin(w * t - phase)))
    assert max(err_x, err_y) <= 1e-8 * amp


def test_free_whirl_transient_decays_to_closed_form():
    # from rest, heavy damping: after the transient the whirl is the closed form
    z, s = 0.4, 1.3
    system = build_system({"rotor": rotor(s, z=z)})
    w = s * WN
    t_end = 60 / (z * WN)
    res = simulate(
        system,
        t_end,
        t_eval=np.linspace(t_end - 2 * math.pi / w, t_end, 50),
        engine="fast",
        rtol=1e-12,
    )
    _, amp, phase = steady_start(s, z=z)
    assert np.max(np.abs(res.output("rotor.x") - amp * np.cos(w * res.t - phase))) <= 1e-8 * amp


@pytest.mark.parametrize("delta,rubs", [(-0.001, False), (0.001, True)])
def test_rub_onset_speed_is_where_the_whirl_grazes(delta, rubs):
    # published onset for z = 0.05, e/d = 0.5: s = 0.8206
    s = 0.8206 + delta
    start, amp, _ = steady_start(s)
    if amp >= D:  # start just inside the stator, on the whirl's phase
        start = {key: value * 0.999 * D / amp for key, value in start.items()}
    st = make_unit("stator", "rigid", dict(clearance=D, restitution=0.8, friction=0.1))
    res = simulate(
        build_system({"rotor": rotor(s, **start), "stator": st}),
        5 * 2 * math.pi / (s * WN),
        output_step=1e-5,
        engine="fast",
    )
    assert res.ok
    assert (res.counters["impacts"] > 0) == rubs
    if not rubs:
        gap = res.output("stator.gap")
        assert 0.0 < gap.min() < 0.01 * D


def test_orbit_grazes_at_onset_speed():
    s = 0.8206
    start, amp, _ = steady_start(s)
    assert abs(amp - D) < 1e-3 * D


def full_rub_amplitude(s, beta, mu, rho=0.5, z=Z):
    """Root A > 1 of A^2[(1-s^2+b(1-1/A))^2+(2zs+b mu(1-1/A))^2] = rho^2 s^4."""

    def f(a):
        q = beta * (1 - 1 / a)
        return a * a * ((1 - s * s + q) ** 2 + (2 * z * s + mu * q) ** 2) - rho**2 * s**4

    return brentq(f, 1.0 + 1e-12, 10.0, xtol=1e-15)


@pytest.mark.parametrize("s,beta,mu", [(1.2, 20.0, 0.02), (1.0, 5.0, 0.04)])
def test_synchronous_full_rub_amplitude_of_penalty_stator(s, beta, mu):
    assert mu * beta < 2 * Z * math.sqrt(1 + beta)  # linearly stable full rub
    a_ref = full_rub_amplitude(s, beta, mu)
    w = s * WN
    r0 = a_ref * D * 1.001
    st = make_unit("stator", "elastic", dict(clearance=D, contact_stiffness=beta * K, friction=mu))
    system = build_system({"rotor": rotor(s, x0=r0, vy0=r0 * w, disc_radius=0.05), "stator": st})
    t_end = 400 * 2 * math.pi / w
    res = simulate(
        system, t_end, t_eval=np.linspace(t_end - 2 * math.pi / w, t_end, 40), engine="fast"
    )
    assert res.ok
    radius = np.hypot(res.output("rotor.x"), res.output("rotor.y")) / D
    assert np.all(np.abs(radius - a_ref) <= 1e-6 * a_ref)


def impact_start_system(stator):
    """Rotor heading straight at the stator from the centre, no unbalance."""
    r = make_unit(
        "rotor", "jeffcott", dict(mass=M, damping=0.0, stiffness=K, speed=0.0, vx0=0.5, vy0=0.1)
    )
    return build_system({"rotor": r, "stator": stator})


def test_frictionless_rigid_impact_in_simulation_scales_normal_velocity():
    r = 0.6
    system = impact_start_system(make_unit("stator", "rigid", dict(clearance=D, restitution=r)))
    res = simulate(system, 2e-4, output_step=1e-6, engine="accurate", rtol=1e-12)
    assert res.counters["impacts"] == 1
    x, y, vx, vy = res.events.state[0]
    n = np.array([x, y]) / math.hypot(x, y)
    t = np.array([-n[1], n[0]])
    # pre-impact velocity from the free motion x = (v0/wn) sin(wn t)
    te = res.events.t[0]
    v_pre = np.array([0.5, 0.1]) * math.cos(WN * te)
    assert math.hypot(x, y) == pytest.approx(D, rel=1e-14)
    assert np.dot([vx, vy], n) == pytest.approx(-r * np.dot(v_pre, n), rel=1e-9)
    assert np.dot([vx, vy], t) == pytest.approx(np.dot(v_pre, t), rel=1e-9)


def test_elastic_stator_converges_to_rigid_as_contact_stiffness_grows():
    r, mu = 0.8, 0.1
    horizon = 3e-3  # a few impacts, before any chattering
    t_eval = np.linspace(0, horizon, 301)
    rigid = simulate(
        impact_start_system(
            make_unit("stator", "rigid", dict(clearance=D, restitution=r, friction=mu))
        ),
        horizon,
        t_eval=t_eval,
        engine="fast",
        rtol=1e-12,
    )
    assert rigid.counters["impacts"] >= 2
    errors = []
    betas = (1e2, 1e3, 1e4, 1e5, 1e6)
    for beta in betas:
        st = make_unit(
            "stator",
            "elastic",
            dict(clearance=D, contact_stiffness=beta * K, restitution=r, friction=mu),
        )
        el = simulate(impact_start_system(st), horizon, t_eval=t_eval, engine="fast", rtol=1e-11)
        assert el.ok
        diff = np.hypot(
            el.output("rotor.x") - rigid.output("rotor.x"),
            el.output("rotor.y") - rigid.output("rotor.y"),
        )
        errors.append(diff.max() / D)
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False)), errors
    # the contact lasts ~ 1/sqrt(kc): the error should fall like kc^(-1/2)
    slope = np.polyfit(np.log(betas[2:]), np.log(errors[2:]), 1)[0]
    assert -0.7 < slope < -0.3, (slope, errors)
    assert errors[-1] < 0.1


def test_chattering_ends_in_sustained_contact_in_finite_time():
    st = make_unit("stator", "rigid", dict(clearance=D, restitution=0.8, friction=0.15))
    s = 1.2
    system = build_system({"rotor": rotor(s, disc_radius=0.05), "stator": st})
    res = simulate(system, 0.5, output_step=1e-3, engine="fast")
    assert res.ok
    assert 10 < res.counters["impacts"] < 1000
    assert res.final_mode != MODE_FREE
    t_last = res.events.t[-1]
    assert t_last < 0.1  # the impacts accumulate and stop: the rest is sliding
    gap = res.output("stator.gap")[res.t > t_last]
    assert np.all(np.abs(gap) < 1e-9 * D)
    assert np.all(res.output("stator.normal_force")[res.t > t_last] > 0)


def test_plastic_impact_sticks_at_once():
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=1.0,
            forcing_amplitude=2.0,
            forcing_frequency=1.0,
            barrier=0.5,
            restitution=0.0,
        ),
    )
    res = simulate(
        build_system({"oscillator": osc}), 3.0, output_step=0.01, engine="accurate", rtol=1e-12
    )
    assert res.ok
    assert res.counters["impacts"] == 1
    assert res.events.mode[0] == MODE_STUCK_UPPER
    # sticking lasts while f cos t - x >= 0 at x = 0.5: release at cos t = 0.25
    release = res.events.t[res.events.of_kind("release")]
    assert release[0] == pytest.approx(math.acos(0.25), rel=1e-10)


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_rolling_contact_sticks_slip(engine):
    # dry whip: the disc rolls backward on the stator without slip (v.t = -Rd w)
    # and friction holds it there; centripetal load keeps the contact closed.
    st = make_unit("stator", "rigid", dict(clearance=D, restitution=0.0, friction=1.0))
    r = make_unit(
        "rotor",
        "jeffcott",
        dict(
            mass=M, stiffness=K, damping=10.0, speed=1.0, disc_radius=0.1, x0=0.999999 * D, vy0=-0.1
        ),
    )
    res = simulate(build_system({"rotor": r, "stator": st}), 2e-3, output_step=1e-5, engine=engine)
    assert res.ok
    assert res.final_mode == MODE_STICK
    assert res.counters["impacts"] == 1
    after = res.t > res.events.t[0]
    radius = np.hypot(res.output("rotor.x"), res.output("rotor.y"))[after]
    speed = np.hypot(res.output("rotor.vx"), res.output("rotor.vy"))[after]
    assert np.all(np.abs(radius - D) < 1e-9 * D)
    assert np.all(np.abs(speed - 0.1) < 1e-9)


def test_event_count_is_bounded_and_reported():
    st = make_unit("stator", "rigid", dict(clearance=D, restitution=0.8, friction=0.15))
    system = build_system({"rotor": rotor(1.2, disc_radius=0.05), "stator": st})
    res = simulate(system, 0.5, output_step=1e-3, engine="fast", max_events=5)
    assert res.status == STATUS_EVENT_LIMIT
    assert "event limit" in res.message
    assert res.t_reached < 0.5


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_rebounds_much_shorter_than_the_step_follow_the_closed_form(engine):
    # A mass pushed onto a rigid barrier by a force that is constant over the run
    # (forcing frequency 1e-6): from rest at x = 0.5, it reaches x = 1 at t = 1 with
    # speed 1; each rebound (restitution r) flies 2 r^k, so impact k (k = 0, 1, ...) is
    # at t_k = 1 + 2 r (1 - r^k) / (1 - r).  With r = 0.05 every flight is 20 times
    # shorter than the one before, while the step after an impact keeps the length of
    # the last accepted one (the motion is quadratic: no error): the return of the
    # third and fourth rebounds lies 2**-11 to 2**-18 of a step in, found from the rate
    # (turned by the step's end: the top is located, and the return after it).
    r = 0.05
    osc = make_unit(
        "oscillator",
        "impact_oscillator",
        dict(
            linear_stiffness=0.0,
            forcing_amplitude=1.0,
            forcing_frequency=1e-6,
            barrier=1.0,
            restitution=r,
            x0=0.5,
        ),
    )
    res = simulate(
        build_system({"oscillator": osc}), 2.0, output_step=0.1, engine=engine, rtol=1e-10
    )
    assert res.ok
    t_imp = res.events.t[res.events.of_kind("impact")]
    # rebound k flies 2 r^(k+1) s and rises r^(2k+2) / 2 m: the flights rising far above
    # the round-off of x (1e-16 m), k <= 3, against the closed form; the later ones
    # (below 1e-13 m, and 1e-5 s, 1e-4 of the step they start) end the sequence at t_inf
    k = np.arange(4)
    expected = 1.0 + 2.0 * r * (1.0 - r**k) / (1.0 - r)
    np.testing.assert_allclose(t_imp[:4], expected, rtol=0, atol=1e-12)
    t_inf = 1.0 + 2.0 * r / (1.0 - r)
    assert t_imp.shape[0] <= 14
    assert np.all(np.abs(t_imp[4:] - t_inf) < 1e-6)
    assert res.final_mode != MODE_FREE  # at rest on the barrier after the sequence
