"""The Hunt-Crossley stator against Hertz's impact (closed forms for the largest
penetration and the contact time), Hunt and Crossley's restitution and the no-tension
rule, on both engines and in the co-simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import beta

from rubcosim.components.graph import make_node
from rubcosim.components.hunt_crossley import hunt_crossley_normal
from rubcosim.reference import build_system, simulate

M, K, D = 10.0, 1e10, 1e-4  # disc mass kg, contact stiffness N/m^1.5, clearance m


def head_on(v: float, e: float = 1.0, v0: float = 0.02, n: float = 1.5):
    """A disc 1 um from a Hunt-Crossley stator, moving onto it at v (m/s), nothing else
    acting (a shaft of 1e-6 N/m, no unbalance, no friction)."""
    rotor = dict(mass=M, stiffness=1e-6, speed=100.0, x0=D - 1e-6, vx0=v)
    stator = dict(clearance=D, contact_stiffness=K, exponent=n, restitution=e, impact_speed=v0)
    return build_system(
        {
            "rotor": make_node("rotor", "jeffcott", rotor),
            "stator": make_node("stator", "hunt_crossley", stator),
        }
    )


def impact(v: float, engine: str, **law):
    res = simulate(head_on(v, **law), 4e-3, output_step=1e-6, engine=engine, rtol=1e-12)
    assert res.ok, res.message
    on, off = res.events.of_kind("contact_on"), res.events.of_kind("contact_off")
    assert on.size == 1 and off.size == 1
    return res, res.events.t[on[0]], res.events.t[off[0]], res.events.state[off[0], 2]


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_elastic_hertz_impact_has_hertz_penetration_contact_time_and_rebound(engine):
    # Hertz (n = 3/2, e = 1): delta_max = (5 m v^2 / (4 k))^(2/5), contact time
    # 2 delta_max / v * (2/5) B(2/5, 1/2) = 2.9432 delta_max / v, rebound at -v
    v = 0.02
    res, t_on, t_off, vx_after = impact(v, engine)
    delta_max = (5.0 * M * v * v / (4.0 * K)) ** 0.4
    contact_time = 2.0 * delta_max / v * 0.4 * beta(0.4, 0.5)
    assert -res.output("stator.gap").min() == pytest.approx(delta_max, rel=1e-5)
    assert t_off - t_on == pytest.approx(contact_time, rel=1e-7)
    assert vx_after == pytest.approx(-v, rel=1e-8)


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_restitution_is_e_at_v0_and_falls_linearly_with_the_impact_speed(engine):
    # Hunt and Crossley: with lambda = 3 k (1 - e) / (2 v0) fixed, 1 - e(v) is close to
    # (1 - e) v / v0 for e near 1 (Lankarani and Nikravesh's energy balance)
    e, v0 = 0.98, 0.02
    for v in (v0, v0 / 4.0):
        _, _, _, vx_after = impact(v, engine, e=e, v0=v0)
        assert 1.0 + vx_after / v == pytest.approx((1.0 - e) * v / v0, rel=0.03)


def test_heavy_damping_never_pulls_and_the_disc_leaves_at_hunt_crossleys_limit():
    # e = 0.1, an impact at 25 v0: on the way out the damper would pull once the
    # penetration rate is below -k / lambda = -2 v0 / (3 (1 - e)).  With no tension the
    # force stays at zero there, so the disc leaves the force while it still
    # penetrates and comes out at exactly that speed
    e, v0 = 0.1, 0.02
    # (the fast engine only: scipy's accurate one takes 20 s over the long force-free exit)
    res, t_on, t_off, vx_after = impact(0.5, "fast", e=e, v0=v0)
    force, gap, t = res.output("stator.normal_force"), res.output("stator.gap"), res.t
    assert force.min() >= 0.0
    inside = (t > t_on) & (t < t_off)
    assert np.count_nonzero((force[inside] == 0.0) & (gap[inside] < 0.0)) > 100
    assert vx_after == pytest.approx(-2.0 * v0 / (3.0 * (1.0 - e)), rel=1e-9)


def test_normal_force_is_the_formula_and_zero_while_clear():
    d, k, n, e, v0 = 1e-4, 1e10, 1.5, 0.8, 0.02
    assert hunt_crossley_normal(d - 1e-6, -0.1, d, k, n, e, v0) == 0.0
    got = hunt_crossley_normal(d + 4e-6, 0.01, d, k, n, e, v0)
    assert got == pytest.approx(k * 4e-6**1.5 * (1.0 + 1.5 * 0.2 * 0.01 / v0), rel=1e-14)
    assert hunt_crossley_normal(d + 4e-6, -1.0, d, k, n, e, v0) == 0.0  # would pull
    assert math.isclose(hunt_crossley_normal(d + 4e-6, 0.0, d, k, 1.0, e, v0), k * 4e-6)
