"""The reference's array layout is derived from the unit declarations: every quantity a
rotor-family unit packs has its own slot, a system holds each unit's values at them,
and a parameter added to a declaration gets a slot with no edit in the reference."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rubcosim.components.bearing import oilfilm_sigma
from rubcosim.components.contact_law import max_law_args
from rubcosim.components.declaration import DeclarationError, Derived
from rubcosim.components.parameters import nonnegative
from rubcosim.components.registry import REGISTRY
from rubcosim.components.stator_unit import ELASTIC_STATOR, ElasticStatorUnit
from rubcosim.reference import layout as L
from rubcosim.reference import system as S
from rubcosim.scenario import load_scenario

SCENARIOS = sorted((Path(__file__).resolve().parents[1] / "scenarios").glob("*.toml"))
FAMILY = [t for t in REGISTRY if t.hybrid is None]


def test_every_packed_quantity_has_its_own_slot_and_every_type_its_own_code():
    slots = list(L.LAYOUT.p.values())
    assert len(set(slots)) == len(slots) and max(slots) < L.N_P
    assert set(slots).isdisjoint({S.P_VCHAT, S.P_OMEGA_B})
    for t in FAMILY:
        for name in L.packed_names(t):
            constant = f"P_{t.role}_{name}".upper()
            assert getattr(S, constant) == L.LAYOUT.p[(t.role, name)]
        assert getattr(S, f"{t.role}_{t.type_name}".upper()) == L.LAYOUT.codes[t.key] > 0
    ints = [*L.LAYOUT.ip_type.values(), *L.LAYOUT.ip_choice.values()]
    ints += [*L.LAYOUT.ip_state.values(), *L.LAYOUT.ip_law.values(), S.IP_FAMILY, S.IP_NSTATE]
    assert sorted(ints) == list(range(L.N_IP))
    # a penalty law's quantities sit side by side, apart from every packed quantity
    assert L.LAYOUT.ip_law["stator"] == S.IP_STATOR_LAW
    law = list(range(S.P_STATOR_LAW_0, S.P_STATOR_LAW_0 + max_law_args()))
    assert set(law).isdisjoint(slots) and max(law) < L.N_P
    # a state's initial value goes to y0, a choice to ip: neither takes a real slot
    assert ("rotor", "x0") not in L.LAYOUT.p and ("controller", "feedback") not in L.LAYOUT.p
    assert S.CONTROLLER_FEEDBACK_VELOCITY == 1


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_a_system_holds_each_units_parameters_and_states_where_the_layout_says(path):
    system = load_scenario(path).system
    if system.family != S.FAMILY_ROTOR:
        return
    units = system.units
    for role, u in units.items():
        assert system.ip[L.LAYOUT.ip_type[role]] == L.LAYOUT.codes[(role, u.type)]
        for p in u.declaration.params:
            if (role, p.name) in L.LAYOUT.p:
                assert system.p[L.LAYOUT.p[(role, p.name)]] == u.params[p.name], p.name
        for s in u.declaration.states:
            offset = system.ip[L.LAYOUT.ip_state[(role, s.name)]]
            assert system.state_names[offset] == f"{role}.{s.name}"
            assert system.y0[offset] == u.params[s.initial]
    absent = [(r, s) for (r, s) in L.LAYOUT.ip_state if r not in units]
    assert all(system.ip[L.LAYOUT.ip_state[k]] == -1 for k in absent)
    if units.get("bearing") and units["bearing"].type == "oilfilm":
        b, w = units["bearing"].params, units["rotor"].params["speed"]
        sigma = oilfilm_sigma(b["viscosity"], w, b["radius"], b["length"], b["clearance"])
        assert system.p[S.P_BEARING_SIGMA] == sigma


def test_a_parameter_added_to_a_declaration_gets_a_slot_and_is_packed():
    wear = nonnegative("wear", 0.0, "m", "radial wear of the stator")
    cls = type("WornStator", (ElasticStatorUnit,), {})
    cls.params_spec = (*ElasticStatorUnit.params_spec, wear)
    worn = dataclasses.replace(
        ELASTIC_STATOR,
        unit_class=cls,
        params=(*ELASTIC_STATOR.params, wear),
        derived=(
            *ELASTIC_STATOR.derived,
            Derived("worn_clearance", "m", "clearance plus wear", lambda q: q["clearance"] + 1),
        ),
    )
    types = [worn if t.key == worn.key else t for t in REGISTRY]
    layout = L.rotor_family_layout(types)
    assert layout.n_p == L.N_P + 2
    assert layout.constants["P_STATOR_WEAR"] == layout.p[("stator", "wear")]
    p, ip = layout.new_arrays()
    values = {"clearance": 2.0, "wear": 0.25, "penalty_damping": 3.0, "worn_clearance": 3.0}
    values |= {n: 0.0 for n in L.packed_names(worn) if n not in values}
    layout.pack("stator", worn, values, p, ip)
    assert p[layout.p[("stator", "wear")]] == 0.25
    assert p[layout.p[("stator", "worn_clearance")]] == 3.0
    assert ip[layout.ip_type["stator"]] == layout.codes[("stator", "elastic")]
    assert np.count_nonzero(ip[list(layout.ip_state.values())] == -1) == len(layout.ip_state)


def test_a_derived_quantity_named_like_a_parameter_is_refused():
    with pytest.raises(DeclarationError, match="derived quantity 'clearance'"):
        dataclasses.replace(ELASTIC_STATOR, derived=(Derived("clearance", "m", "", lambda q: 0.0),))
