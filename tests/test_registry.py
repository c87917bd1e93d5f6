"""The unit registry: one declaration per unit type, and what is derived from it
(catalogue, unit classes, FMU list, default wiring, neighbour parameters, scales)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from rubcosim.components.catalog import UNIT_TYPES
from rubcosim.components.declaration import (
    SCALE_KINDS,
    DeclarationError,
    FmuIdentity,
    Need,
    State,
    UnitType,
    Wire,
)
from rubcosim.components.registry import REGISTRY, Registry
from rubcosim.components.rotor_unit import JEFFCOTT_ROTOR
from rubcosim.components.stator_unit import ELASTIC_STATOR, ElasticStatorUnit
from rubcosim.components.units import UNIT_CLASSES, unit_type
from rubcosim.components.wiring import default_connections
from rubcosim.fmus.build import MODEL_IDENTIFIERS, fmu_specs
from rubcosim.orchestrator.assembly import unit_parameters
from rubcosim.reference import system as S
from rubcosim.scenario import load_scenario

SCENARIOS = sorted((Path(__file__).resolve().parents[1] / "scenarios").glob("*.toml"))


def test_the_catalogue_is_what_every_unit_type_declares():
    assert {
        role: {t.type_name: t.params for t in REGISTRY if t.role == role}
        for role in dict.fromkeys(t.role for t in REGISTRY)
    } == UNIT_TYPES
    assert list(UNIT_CLASSES) == [t.key for t in REGISTRY]
    for t in REGISTRY:
        cls = UNIT_CLASSES[t.key]
        assert (cls.role, cls.type_name) == t.key and t.unit_class is cls
        assert set(t.params) <= set(cls.params_spec)
        assert (t.summary, t.inputs, t.outputs) == (cls.summary, cls.inputs, cls.outputs)
        outputs = {s.name: s.unit for s in cls.outputs}
        for s in t.states:  # every state is published under its name, in its unit
            assert outputs[s.name] == s.unit == SCALE_KINDS[s.scale]
        for need in t.needs:
            assert need.param in {p.name for p in cls.params_spec}
        assert unit_type(*t.key) is t


def test_the_fmu_list_is_what_every_unit_type_declares():
    assert {t.key: t.fmu.identifier for t in REGISTRY} == MODEL_IDENTIFIERS
    assert [(s.identifier, s.unit_class) for s in fmu_specs()] == [
        (t.fmu.identifier, t.unit_class) for t in REGISTRY
    ]
    assert len(set(MODEL_IDENTIFIERS.values())) == len(MODEL_IDENTIFIERS)
    assert JEFFCOTT_ROTOR.fmu.file_name == "RubcosimJeffcottRotor.fmu"


# --------------------------------------------------------------------------- wiring
def _role_rules(types):
    """The role-based wiring written by hand before the declarations (the oracle)."""
    links = {}
    if "rotor" not in types:
        return links
    disc = ("x", "y", "vx", "vy")
    stator, controller, bearing = (types.get(r) for r in ("stator", "controller", "bearing"))
    for role in ("stator", "controller"):
        if types.get(role):
            for s in disc:
                links[f"{role}.{s}"] = (f"rotor.{s}",)
    for axis, u in (("x", "ux"), ("y", "uy")):
        force = ([f"stator.f{axis}"] if stator else []) + (
            [f"controller.{u}"] if controller else []
        )
        if force:
            links[f"rotor.f{axis}"] = tuple(force)
        if stator == "rigid":
            others = [f"rotor.force_{axis}"] + ([f"controller.{u}"] if controller else [])
            links[f"stator.other_f{axis}"] = tuple(others)
        if bearing:
            links[f"rotor.journal_f{axis}"] = (f"bearing.f{axis}",)
    if bearing:
        for s in disc:
            links[f"bearing.{s}"] = (f"rotor.journal_{s}",)
    return links


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_default_connections_of_every_scenario(path):
    sc = load_scenario(path)
    types = {role: u.type for role, u in sc.system.units.items()}
    new = [(c.target, c.sources) for c in default_connections(types)]
    assert dict(new) == _role_rules(types) and len(new) == len(dict(new))


def test_default_connections_of_the_flagship_spelled_out():
    sc = load_scenario(SCENARIOS[0].with_name("jeffcott_rigid_stator.toml"))
    types = {role: u.type for role, u in sc.system.units.items()}
    assert {c.target: c.sources for c in default_connections(types)} == {
        **{f"stator.{s}": (f"rotor.{s}",) for s in ("x", "y", "vx", "vy")},
        "rotor.fx": ("stator.fx",),
        "rotor.fy": ("stator.fy",),
        "stator.other_fx": ("rotor.force_x",),
        "stator.other_fy": ("rotor.force_y",),
    }


def test_default_connections_of_every_valid_combination_of_types():
    for rotor, stator, bearing, ctl in itertools.product(
        ("jeffcott", "two_mass"), (None, "rigid", "elastic", "casing"),
        (None, "oilfilm", "linear"), (None, "delayed_feedback"),
    ):  # fmt: skip
        if (rotor == "two_mass") != (bearing is not None):
            continue  # the reference refuses a bearing without a journal and vice versa
        given = {"rotor": rotor, "stator": stator, "bearing": bearing, "controller": ctl}
        types = {role: t for role, t in given.items() if t}
        got = {c.target: c.sources for c in default_connections(types)}
        assert got == _role_rules(types), types


# --------------------------------------------------------------------------- parameters, scales
@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_neighbour_parameters_and_state_scales_match_the_reference(path):
    sc = load_scenario(path)
    system, units = sc.system, sc.system.units
    params = unit_parameters(sc, sc.cosim)
    if "rotor" in units:
        r = units["rotor"].params
        for role in ("stator", "controller"):
            if role in units:
                assert params[role]["speed"] == r["speed"]
        if units.get("bearing") and units["bearing"].type == "oilfilm":
            assert params["bearing"]["speed"] == r["speed"]
        stator = units.get("stator")
        if stator is not None and stator.type == "rigid":
            assert params["stator"]["constraint_rate"] == system.p[S.P_OMEGA_B]
            assert params["stator"]["disc_mass"] == r["mass"]
        if stator is not None and stator.type == "casing":
            m, ms = r["mass"], stator.params["mass"]
            assert params["stator"]["impact_mass"] == m * ms / (m + ms)
    # every state the reference integrates is declared, with the scale of its kind
    kinds = REGISTRY.state_scales({role: u.type for role, u in units.items()})
    assert set(kinds) == set(system.state_names)
    for name, scale in zip(system.state_names, system.state_scale, strict=True):
        expected = system.velocity_scale if kinds[name] == "velocity" else system.state_scale[0]
        assert scale == expected, name


def test_constraint_rate_is_the_faster_of_spin_and_natural_frequency():
    (provided,) = [p for p in JEFFCOTT_ROTOR.provides if p.name == "constraint_rate"]
    slow = {"speed": 10.0, "stiffness": 1e6, "mass": 10.0}
    assert provided.value(slow) == math.sqrt(1e5)
    assert provided.value({**slow, "speed": 1e3}) == 1e3


# --------------------------------------------------------------------------- refusals
def test_a_state_without_a_scale_is_refused_naming_it():
    with pytest.raises(DeclarationError, match=r"stator\.elastic: state 'q' has no scale"):
        UnitType(
            ElasticStatorUnit,
            ELASTIC_STATOR.params,
            FmuIdentity("X"),
            states=(State("q", "m", ""),),
        )
    with pytest.raises(DeclarationError, match=r"state 'q' is in 'm' but a velocity"):
        UnitType(
            ElasticStatorUnit,
            ELASTIC_STATOR.params,
            FmuIdentity("X"),
            states=(State("q", "m", "velocity"),),
        )


def test_a_wire_from_an_unknown_neighbour_output_is_refused_naming_it():
    bad = UnitType(
        ElasticStatorUnit,
        ELASTIC_STATOR.params,
        FmuIdentity("X"),
        wiring=(Wire("x", ("rotor.position_x",)),),
    )
    others = tuple(t for t in REGISTRY if t.key != ELASTIC_STATOR.key)
    with pytest.raises(
        DeclarationError, match=r"stator\.elastic: wire to 'x' from 'rotor\.position_x': no rotor"
    ):
        Registry((*others, bad))


def test_other_bad_entries_are_refused_naming_them():
    def declare(**kw):
        return UnitType(ElasticStatorUnit, ELASTIC_STATOR.params, FmuIdentity("X"), **kw)

    with pytest.raises(DeclarationError, match="wire to 'z': not an input"):
        declare(wiring=(Wire("z", ("rotor.x",)),))
    with pytest.raises(DeclarationError, match="'rotorx' is not of the form role.name"):
        declare(wiring=(Wire("x", ("rotorx",)),))
    with pytest.raises(DeclarationError, match="need 'spin': 'spin' is not a parameter"):
        declare(needs=(Need("spin", "rotor.speed"),))
    others = tuple(t for t in REGISTRY if t.key != ELASTIC_STATOR.key)
    with pytest.raises(DeclarationError, match="need 'speed' from 'rotor.spin': no rotor"):
        Registry((*others, declare(needs=(Need("speed", "rotor.spin"),))))
    with pytest.raises(DeclarationError, match=r"stator\.elastic is declared twice"):
        Registry((*REGISTRY.types, ELASTIC_STATOR))


def test_a_contact_law_reading_an_unknown_quantity_is_refused_naming_it():
    from rubcosim.components.contact_law import ContactLaw
    from rubcosim.components.stator import penalty_normal

    law = ContactLaw("penalty", penalty_normal, ("clearance", "stiffness_kc"))
    with pytest.raises(DeclarationError, match="contact law: 'stiffness_kc' is not a parameter"):
        UnitType(ElasticStatorUnit, ELASTIC_STATOR.params, FmuIdentity("X"), contact=law)
    with pytest.raises(ValueError, match="only a penalty contact, has a normal law"):
        ContactLaw("rigid", penalty_normal)
    with pytest.raises(ValueError, match="contact kind 'soft' is not one of"):
        ContactLaw("soft")


def test_every_stator_type_declares_its_contact_and_the_penalty_laws_are_listed_once():
    from rubcosim.components.contact_law import penalty_laws

    stators = [t for t in REGISTRY if t.role == "stator"]
    assert all(t.contact is not None for t in stators)
    declared = [t.contact for t in stators if t.contact.kind == "penalty"]
    assert list(penalty_laws()) == list(dict.fromkeys(declared))
    # the elastic stator and the casing share the Kelvin-Voigt law
    assert unit_type("stator", "elastic").contact is unit_type("stator", "casing").contact
