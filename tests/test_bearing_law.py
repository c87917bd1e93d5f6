"""Bearings declare their force law (components/bearing_law.py): the reference and the
co-simulation's rows reach it through one generated dispatch, and a law that names
what its type does not have is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.components import bearing_law
from rubcosim.components.bearing import linear_bearing_force, oilfilm_force
from rubcosim.components.bearing_unit import LINEAR_BEARING, OILFILM_BEARING, LinearBearingUnit
from rubcosim.components.declaration import DeclarationError, FmuIdentity, UnitType
from rubcosim.components.flat_params import flat_params, flat_type
from rubcosim.components.flat_units import K_BEARING
from rubcosim.reference import system as S


def test_every_bearing_type_is_a_law_of_the_generated_dispatch_in_registry_order():
    # wiring: the dispatch's branches follow the registry, each law once
    laws = bearing_law.bearing_laws()
    assert laws == (OILFILM_BEARING.bearing, LINEAR_BEARING.bearing)
    assert [bearing_law.law_index(t.bearing) for t in (OILFILM_BEARING, LINEAR_BEARING)] == [0, 1]
    assert bearing_law.law_index(None) == -1
    for t in (OILFILM_BEARING, LINEAR_BEARING):
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
