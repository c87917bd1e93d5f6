"""Bearings declare their force law (components/bearing_law.py): the reference and the
co-simulation's rows reach it through one generated dispatch, and a law that names
what its type does not have is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.components import bearing_law
from rubcosim.components.anisotropic_bearing import ANISOTROPIC_BEARING
from rubcosim.components.bearing import linear_bearing_force, oilfilm_force
from rubcosim.components.bearing_unit import LINEAR_BEARING, OILFILM_BEARING, LinearBearingUnit
from rubcosim.components.declaration import DeclarationError, FmuIdentity, UnitType
from rubcosim.components.flat_params import flat_params, flat_type
from rubcosim.components.flat_units import K_BEARING
from rubcosim.reference import build_system, make_unit, simulate
from rubcosim.reference import system as S


def test_every_bearing_type_is_a_law_of_the_generated_dispatch_in_registry_order():
    # wiring: the dispatch's branches follow the registry, each law once
    types = (OILFILM_BEARING, LINEAR_BEARING, ANISOTROPIC_BEARING)
    assert bearing_law.bearing_laws() == tuple(t.bearing for t in types)
    assert [bearing_law.law_index(t.bearing) for t in types] == [0, 1, 2]
    assert bearing_law.law_index(None) == -1
    for t in types:
        assert flat_type("bearing", t.type_name)[0] == K_BEARING


def test_the_dispatch_gives_the_linear_law_in_closed_form():
    k, c = 2.5e7, 340.0
    p = np.array([9.0, k, c])  # a head slot, then the law's quantities
    x, y, vx, vy = 3e-5, -1e-5, 0.02, -0.05
    fx, fy = bearing_law.bearing_law_force(1, x, y, vx, vy, p, 1)
    assert (fx, fy) == (-k * x - c * vx, -k * y - c * vy)
    assert bearing_law.bearing_law_force(-1, x, y, vx, vy, p, 1) == (0.0, 0.0)


def test_the_reference_packs_the_bearing_law_of_its_scenario():
    system = rc.load("two_mass_oilfilm_rub").system
    ip, p = system.ip, system.p
    assert ip[S.IP_BEARING_LAW] == bearing_law.law_index(OILFILM_BEARING.bearing)
    speed, clearance, sigma = p[S.P_BEARING_LAW_0], p[S.P_BEARING_LAW_1], p[S.P_BEARING_LAW_2]
    assert (speed, clearance, sigma) == (
        p[S.P_ROTOR_SPEED], p[S.P_BEARING_CLEARANCE], p[S.P_BEARING_SIGMA]
    )  # fmt: skip
    # the journal's force as the reference's right-hand side computes it
    y = np.zeros(int(ip[S.IP_NSTATE]))
    j = int(ip[S.IP_ROTOR_JOURNAL_X])
    y[j : j + 4] = 1e-5, 2e-5, 0.01, -0.02
    want = oilfilm_force(1e-5, 2e-5, 0.01, -0.02, speed, clearance, sigma)
    assert S.bearing_force(y, p, ip) == want


def test_the_oil_film_row_carries_its_derived_force_scale():
    q = {"viscosity": 0.02, "radius": 0.03, "length": 0.03, "clearance": 1.5e-4, "speed": 700.0}
    row = flat_params("bearing", "oilfilm", q)
    sigma = OILFILM_BEARING.derived[0].value(q)
    assert row[0] == 0 and tuple(row[1:4]) == (700.0, 1.5e-4, sigma)
    assert bearing_law.wall_ratio(0, 3e-4, 4e-4, row[1:]) == pytest.approx(5e-4 / 1.5e-4)
    assert bearing_law.wall_ratio(1, 3e-4, 4e-4, row[1:]) == 0.0  # no wall
    assert math.isfinite(sigma) and sigma > 0.0


def test_a_bearing_law_naming_what_its_type_lacks_is_refused():
    with pytest.raises(ValueError, match="wall 'gap' is not one of its args"):
        bearing_law.BearingLaw(linear_bearing_force, ("stiffness", "damping"), wall="gap")
    with pytest.raises(DeclarationError, match=r"bearing\.linear: bearing law: 'k3'"):
        UnitType(
            LinearBearingUnit,
            LINEAR_BEARING.params,
            FmuIdentity("X"),
            bearing=bearing_law.BearingLaw(linear_bearing_force, ("stiffness", "k3")),
        )


# A two-mass rotor without unbalance or gravity on the anisotropic bearing is a linear
# system: its free motion is exp(A t) y0, with A written here from the equations of
# motion (disc m, shaft k and cs to the journal mj, damping c and cj to ground, bearing
# F = -Kb q - Cb q'), apart from the code's kernels.
DISC = dict(mass=10.0, damping=20.0, stiffness=5e6, shaft_damping=50.0, journal_mass=2.0)
BEARING = dict(kxx=2e7, kyy=1.2e7, kxy=1.5e6, kyx=-1.5e6, cxx=4e3, cyy=3e3, cxy=200.0, cyx=-100.0)


def state_matrix(d: dict, b: dict) -> np.ndarray:
    m, c, k, cs, mj = d["mass"], d["damping"], d["stiffness"], d["shaft_damping"], d["journal_mass"]
    kb = np.array([[b["kxx"], b["kxy"]], [b["kyx"], b["kyy"]]])
    cb = np.array([[b["cxx"], b["cxy"]], [b["cyx"], b["cyy"]]])
    eye = np.eye(2)
    # q = (x, y, xj, yj): M q'' + C q' + K q = 0
    mass = np.diag([m, m, mj, mj])
    damp = np.block([[(c + cs) * eye, -cs * eye], [-cs * eye, cs * eye + cb]])
    stiff = np.block([[k * eye, -k * eye], [-k * eye, k * eye + kb]])
    a = np.zeros((8, 8))
    a[:4, 4:] = np.eye(4)
    a[4:, :4] = -np.linalg.solve(mass, stiff)
    a[4:, 4:] = -np.linalg.solve(mass, damp)
    return a


@pytest.mark.parametrize("engine", ["fast", "accurate"])
def test_free_motion_on_a_cross_coupled_bearing_is_the_matrix_exponential(engine):
    from scipy.linalg import expm

    x0 = dict(x0=3e-5, y0=-1e-5, vx0=0.0, vy0=0.02, journal_x0=1e-5, journal_vy0=-0.01)
    rest = {"eccentricity": 0.0, "speed": 600.0, "gravity": 0.0}
    rotor = make_unit("rotor", "two_mass", {**DISC, **x0, **rest})
    bearing = make_unit("bearing", "anisotropic", dict(BEARING))
    system = build_system({"rotor": rotor, "bearing": bearing})
    t = np.linspace(0.0, 0.02, 41)
    res = simulate(system, t[-1], t_eval=t, engine=engine, rtol=1e-11)
    assert res.ok
    names = ("rotor.x", "rotor.y", "rotor.journal_x", "rotor.journal_y")
    got = np.array([res.output(n) for n in names])
    # state order of state_matrix: (x, y, xj, yj, vx, vy, vxj, vyj)
    y0 = np.array([3e-5, -1e-5, 1e-5, 0.0, 0.0, 0.02, 0.0, -0.01])
    a = state_matrix(DISC, BEARING)
    want = np.array([expm(a * ti) @ y0 for ti in t])[:, :4].T
    scale = np.max(np.abs(want))
    assert np.max(np.abs(got - want)) <= 1e-8 * scale


def test_cross_coupling_past_the_threshold_makes_the_free_whirl_grow_at_the_eigenvalue_rate():
    # enough cross-coupled stiffness (kxy = -kyx) destabilises forward whirl: the run grows
    # at the largest real part of A's eigenvalues (the model's own instability, reported
    # as it is, not damped away)
    strong = {**BEARING, "kxy": 2.5e7, "kyx": -2.5e7}
    rate = max(np.linalg.eigvals(state_matrix(DISC, strong)).real)
    assert rate > 0.0
    x0 = dict(x0=1e-6, journal_x0=0.0)
    rest = {"eccentricity": 0.0, "speed": 600.0, "gravity": 0.0}
    rotor = make_unit("rotor", "two_mass", {**DISC, **x0, **rest})
    bearing = make_unit("bearing", "anisotropic", strong)
    system = build_system({"rotor": rotor, "bearing": bearing})
    # from 10 to 20 e-foldings, where the unstable mode has outgrown the others
    t = np.linspace(10.0 / rate, 20.0 / rate, 2001)
    res = simulate(system, t[-1], t_eval=t, engine="fast", rtol=1e-11)
    assert res.ok
    r = np.hypot(res.output("rotor.x"), res.output("rotor.y"))
    # log |r| rises as rate * t; its oscillation (an elliptic whirl) averages out of a fit
    # over many periods
    grown = np.polyfit(t, np.log(r), 1)[0]
    assert grown == pytest.approx(rate, rel=0.02)
