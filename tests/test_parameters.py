"""Parameter declarations (Param.coerce, resolve) and the assembler's cross-unit checks."""

import math

import pytest

from rubcosim.components.catalog import UNIT_TYPES
from rubcosim.components.controller import CONTROLLER_PARAMS
from rubcosim.components.graph import UnitNode as Unit
from rubcosim.components.graph import make_node as make_unit
from rubcosim.components.oscillator import OSCILLATOR_PARAMS, STOP_KINDS
from rubcosim.components.parameters import (
    Param,
    ParameterError,
    choice,
    nonnegative,
    positive,
    real,
    resolve,
)
from rubcosim.components.rotor import JEFFCOTT_PARAMS
from rubcosim.components.stator import ELASTIC_PARAMS, RIGID_PARAMS
from rubcosim.reference.assemble import build_system


def spec(specs, name):
    return {p.name: p for p in specs}[name]


def raises_param(match_all, func, *args):
    """Call ``func`` and check it raises ParameterError whose message has every string."""
    with pytest.raises(ParameterError) as info:
        func(*args)
    msg = str(info.value)
    for text in match_all:
        assert text in msg, f"{text!r} not in {msg!r}"
    return msg


# --------------------------------------------------------------------------- allowed()


def test_allowed_texts():
    assert positive("m", None, "kg", "").allowed() == "a real number in (0, inf]"
    assert nonnegative("c", 0.0, "", "").allowed() == "a real number in [0, inf]"
    assert real("r", 0.5, "", "", 0.0, 1.0).allowed() == "a real number in [0, 1]"
    assert real("r", 0.5, "", "", 0.0, 1.0, high_open=True).allowed() == "a real number in [0, 1)"
    assert real("x", 0.0, "", "").allowed() == "a real number in [-inf, inf]"
    assert choice("s", "a", "", ("a", "b")).allowed() == "one of 'a', 'b'"
    assert Param("f", False, "", "", "bool").allowed() == "true or false"
    assert "[1, 1e+06]" in spec(CONTROLLER_PARAMS, "delay_periods").allowed()
    assert spec(CONTROLLER_PARAMS, "delay_periods").allowed() == "an integer in [1, 1e+06]"


# --------------------------------------------------------------------------- real


def test_real_accepts_int_and_float_and_returns_float():
    p = positive("mass", None, "kg", "disc mass")
    v = p.coerce("rotor", 10)
    assert v == 10.0 and type(v) is float
    assert p.coerce("rotor", 2.5) == 2.5


def test_negative_mass_is_rejected_with_field_and_range():
    p = spec(JEFFCOTT_PARAMS, "mass")
    raises_param(["rotor.mass", "-1", "(0, inf]"], p.coerce, "rotor", -1.0)


def test_open_lower_bound_excludes_the_bound():
    p = spec(JEFFCOTT_PARAMS, "mass")
    raises_param(["rotor.mass", "(0, inf]"], p.coerce, "rotor", 0.0)
    assert p.coerce("rotor", 1e-300) == 1e-300


def test_closed_bounds_include_the_bounds():
    p = spec(RIGID_PARAMS, "restitution")
    assert p.coerce("stator", 0.0) == 0.0
    assert p.coerce("stator", 1.0) == 1.0
    raises_param(["stator.restitution", "[0, 1]"], p.coerce, "stator", -1e-12)
    raises_param(["stator.restitution", "[0, 1]"], p.coerce, "stator", 1.0 + 1e-12)


def test_open_upper_bound_excludes_the_bound():
    p = real("fraction", 0.5, "1", "a fraction", 0.0, 1.0, high_open=True)
    assert p.coerce("u", 0.999) == 0.999
    raises_param(["u.fraction", "[0, 1)"], p.coerce, "u", 1.0)


def test_nonnegative_accepts_zero_rejects_negative():
    p = spec(JEFFCOTT_PARAMS, "damping")
    assert p.coerce("rotor", 0) == 0.0
    raises_param(["rotor.damping", "[0, inf]"], p.coerce, "rotor", -0.1)


@pytest.mark.parametrize(
    ("specs", "unit"),
    [(RIGID_PARAMS, "stator"), (ELASTIC_PARAMS, "stator"), (OSCILLATOR_PARAMS, "oscillator")],
    ids=["rigid_stator", "elastic_stator", "oscillator"],
)
def test_restitution_outside_unit_interval(specs, unit):
    p = spec(specs, "restitution")
    raises_param([f"{unit}.restitution", "1.5", "[0, 1]"], p.coerce, unit, 1.5)
    raises_param([f"{unit}.restitution", "[0, 1]"], p.coerce, unit, -0.5)


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_real_non_finite_is_rejected(value):
    p = spec(OSCILLATOR_PARAMS, "x0")  # unbounded: only finiteness stops inf
    raises_param(["oscillator.x0", "not finite"], p.coerce, "oscillator", value)
    p = spec(JEFFCOTT_PARAMS, "mass")
    raises_param(["rotor.mass"], p.coerce, "rotor", value)


def test_real_non_finite_message_states_allowed_range():
    p = spec(JEFFCOTT_PARAMS, "mass")
    raises_param(["rotor.mass", "(0, inf]"], p.coerce, "rotor", math.inf)


@pytest.mark.parametrize("value", ["10", "abc", None, [1.0], {"a": 1}, 1j])
def test_real_rejects_non_numbers(value):
    p = spec(JEFFCOTT_PARAMS, "mass")
    raises_param(["rotor.mass", "not a number", "(0, inf]"], p.coerce, "rotor", value)


@pytest.mark.parametrize("value", [True, False])
def test_real_rejects_bool(value):
    p = spec(RIGID_PARAMS, "restitution")
    raises_param(["stator.restitution", "not a number", "[0, 1]"], p.coerce, "stator", value)


# --------------------------------------------------------------------------- int


def test_int_accepts_integral_values_and_returns_int():
    p = spec(CONTROLLER_PARAMS, "delay_periods")
    for given in (1, 3, 3.0, 1e6):
        v = p.coerce("controller", given)
        assert v == int(given) and type(v) is int


def test_int_rejects_fraction_bool_string():
    p = spec(CONTROLLER_PARAMS, "delay_periods")
    raises_param(["controller.delay_periods", "not an integer"], p.coerce, "controller", 2.5)
    raises_param(["controller.delay_periods", "not a number"], p.coerce, "controller", True)
    raises_param(["controller.delay_periods", "not a number"], p.coerce, "controller", "2")


def test_int_range_is_checked():
    p = spec(CONTROLLER_PARAMS, "delay_periods")
    raises_param(["controller.delay_periods", "[1, 1e+06]"], p.coerce, "controller", 0)
    raises_param(["controller.delay_periods", "[1, 1e+06]"], p.coerce, "controller", 10**6 + 1)


def test_int_fraction_message_states_allowed_range():
    p = spec(CONTROLLER_PARAMS, "delay_periods")
    raises_param(["controller.delay_periods", "[1, 1e+06]"], p.coerce, "controller", 2.5)


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_int_non_finite_is_a_parameter_error(value):
    p = spec(CONTROLLER_PARAMS, "delay_periods")
    raises_param(["controller.delay_periods"], p.coerce, "controller", value)


# --------------------------------------------------------------------------- bool


def test_bool_accepts_bools_and_true_false_strings():
    p = Param("flag", False, "", "a switch", "bool")
    assert p.coerce("u", True) is True
    assert p.coerce("u", False) is False
    assert p.coerce("u", "true") is True
    assert p.coerce("u", "FALSE") is False
    assert p.coerce("u", "True") is True


@pytest.mark.parametrize("value", [1, 0, 1.0, "yes", "", None])
def test_bool_rejects_everything_else(value):
    p = Param("flag", False, "", "a switch", "bool")
    raises_param(["u.flag", "true or false"], p.coerce, "u", value)


# --------------------------------------------------------------------------- choice


def test_choice_accepts_every_choice():
    p = spec(OSCILLATOR_PARAMS, "stop")
    for kind in STOP_KINDS:
        assert p.coerce("oscillator", kind) == kind


@pytest.mark.parametrize("value", ["rigid", "RIGID_ONE_SIDED", 1, None, True, ["none"]])
def test_choice_rejects_other_values(value):
    p = spec(OSCILLATOR_PARAMS, "stop")
    msg = raises_param(["oscillator.stop", "one of"], p.coerce, "oscillator", value)
    for kind in STOP_KINDS:
        assert repr(kind) in msg


# --------------------------------------------------------------------------- resolve

ROTOR = {"mass": 10.0, "stiffness": 1.0e6, "speed": 379.473319, "eccentricity": 5.0e-5}


def test_resolve_fills_defaults_and_coerces():
    values = resolve("rotor", JEFFCOTT_PARAMS, {"mass": 10, "stiffness": 1e6, "speed": 100})
    assert set(values) == {p.name for p in JEFFCOTT_PARAMS}
    assert values["mass"] == 10.0 and type(values["mass"]) is float
    for p in JEFFCOTT_PARAMS:
        if p.name not in ("mass", "stiffness", "speed"):
            assert values[p.name] == p.default


def test_resolve_does_not_modify_given():
    given = dict(ROTOR)
    resolve("rotor", JEFFCOTT_PARAMS, given)
    assert given == ROTOR


def test_resolve_unknown_name():
    msg = raises_param(
        ["rotor.masss", "not a parameter", "mass", "stiffness"],
        resolve,
        "rotor",
        JEFFCOTT_PARAMS,
        {**ROTOR, "masss": 1.0},
    )
    assert "known:" in msg


def test_resolve_unknown_reported_before_missing():
    raises_param(["rotor.zzz"], resolve, "rotor", JEFFCOTT_PARAMS, {"zzz": 1})


@pytest.mark.parametrize("missing", ["mass", "stiffness", "speed"])
def test_resolve_missing_required(missing):
    given = {k: v for k, v in ROTOR.items() if k != missing}
    raises_param([f"rotor.{missing}", "required"], resolve, "rotor", JEFFCOTT_PARAMS, given)


def test_resolve_bad_value_names_field():
    raises_param(
        ["rotor.mass", "(0, inf]"], resolve, "rotor", JEFFCOTT_PARAMS, {**ROTOR, "mass": -1.0}
    )
    raises_param(
        ["stator.restitution", "[0, 1]"],
        resolve,
        "stator",
        RIGID_PARAMS,
        {"clearance": 1e-4, "restitution": 1.5},
    )
    raises_param(
        ["oscillator.restitution", "[0, 1]"],
        resolve,
        "oscillator",
        OSCILLATOR_PARAMS,
        {"linear_stiffness": 1.0, "forcing_frequency": 2.0, "restitution": 1.5},
    )


def test_every_declared_param_is_well_formed():
    for role, kinds in UNIT_TYPES.items():
        for type_, specs in kinds.items():
            names = [p.name for p in specs]
            assert len(names) == len(set(names)), f"{role}.{type_} declares a name twice"
            assert "type" not in names
            for p in specs:
                assert p.kind in ("real", "int", "bool", "choice")
                if p.default is not None:
                    # every default must itself be allowed
                    assert p.coerce(role, p.default) == p.default, f"{role}.{p.name}"


# --------------------------------------------------------------------------- make_unit

TWO_MASS = {**ROTOR, "journal_mass": 2.0}
RIGID = {"clearance": 1.0e-4, "restitution": 0.8, "friction": 0.15}
ELASTIC = {"clearance": 1.0e-4, "contact_stiffness": 2.0e7}
OILFILM = {"viscosity": 0.02, "radius": 0.03, "length": 0.03, "clearance": 1.5e-4}
LINEAR = {"stiffness": 1.0e7}
CONTROLLER = {"gain": 100.0}
OSC = {"linear_stiffness": 1.0, "forcing_frequency": 2.0, "forcing_amplitude": 1.0}


def units(**spec_by_role):
    """``units(rotor=("jeffcott", {...}), ...)`` -> validated units."""
    return {role: make_unit(role, t, given) for role, (t, given) in spec_by_role.items()}


def test_make_unit_ok():
    u = make_unit("rotor", "jeffcott", ROTOR)
    assert isinstance(u, Unit)
    assert (u.role, u.type) == ("rotor", "jeffcott")
    assert u.params["mass"] == 10.0


def test_make_unit_unknown_role():
    raises_param(["'casing'", "not known", "rotor", "oscillator"], make_unit, "casing", "x", {})


def test_make_unit_unknown_type():
    raises_param(
        ["rotor.type", "'three_mass'", "jeffcott", "two_mass"],
        make_unit,
        "rotor",
        "three_mass",
        ROTOR,
    )


def test_make_unit_bad_param_names_field():
    raises_param(["rotor.mass", "(0, inf]"], make_unit, "rotor", "jeffcott", {**ROTOR, "mass": -1})
    raises_param(
        ["stator.restitution", "[0, 1]"],
        make_unit,
        "stator",
        "rigid",
        {**RIGID, "restitution": 1.5},
    )
    raises_param(
        ["oscillator.restitution", "[0, 1]"],
        make_unit,
        "oscillator",
        "impact_oscillator",
        {**OSC, "restitution": 1.5},
    )


# --------------------------------------------------------------------------- build_system


def test_build_system_valid_combinations():
    build_system(units(rotor=("jeffcott", ROTOR)))
    build_system(units(rotor=("jeffcott", ROTOR), stator=("rigid", RIGID)))
    build_system(units(rotor=("jeffcott", ROTOR), stator=("elastic", ELASTIC)))
    build_system(units(rotor=("two_mass", TWO_MASS), bearing=("oilfilm", OILFILM)))
    build_system(units(rotor=("two_mass", TWO_MASS), bearing=("linear", LINEAR)))
    build_system(units(rotor=("jeffcott", ROTOR), controller=("delayed_feedback", CONTROLLER)))
    for stop in STOP_KINDS:
        q = {**OSC, "stop": stop, "stop_stiffness": 10.0}
        build_system(units(oscillator=("impact_oscillator", q)))


def test_no_rotor_and_no_oscillator():
    raises_param(["rotor", "oscillator"], build_system, units(stator=("rigid", RIGID)))


def test_bearing_without_two_mass_rotor():
    u = units(rotor=("jeffcott", ROTOR), bearing=("linear", LINEAR))
    raises_param(["bearing", "two_mass"], build_system, u)


def test_two_mass_without_bearing():
    u = units(rotor=("two_mass", TWO_MASS))
    raises_param(["rotor.type", "two_mass", "bearing"], build_system, u)


@pytest.mark.parametrize(
    ("role", "type_", "given"),
    [
        ("rotor", "jeffcott", ROTOR),
        ("stator", "rigid", RIGID),
        ("controller", "delayed_feedback", CONTROLLER),
    ],
)
def test_oscillator_cannot_be_combined(role, type_, given):
    u = units(oscillator=("impact_oscillator", OSC), **{role: (type_, given)})
    raises_param([repr(role), "oscillator"], build_system, u)


def test_rigid_stator_initial_disc_outside_clearance():
    u = units(rotor=("jeffcott", {**ROTOR, "x0": 1.5e-4}), stator=("rigid", RIGID))
    raises_param(["rotor.x0", "clearance"], build_system, u)
    # relative to the offset stator centre
    u = units(
        rotor=("jeffcott", {**ROTOR, "y0": -1.5e-4}),
        stator=("rigid", {**RIGID, "y_offset": -1.0e-4}),
    )
    build_system(u)
    u = units(
        rotor=("jeffcott", {**ROTOR, "y0": 0.8e-4}),
        stator=("rigid", {**RIGID, "y_offset": -1.0e-4}),
    )
    raises_param(["rotor.x0", "clearance"], build_system, u)


def test_rigid_stator_initial_disc_on_clearance_is_allowed():
    u = units(rotor=("jeffcott", {**ROTOR, "x0": 1.0e-4}), stator=("rigid", RIGID))
    assert build_system(u).y0[0] == 1.0e-4


def test_elastic_stator_may_start_in_penetration():
    u = units(rotor=("jeffcott", {**ROTOR, "x0": 1.5e-4}), stator=("elastic", ELASTIC))
    build_system(u)


def test_journal_outside_oilfilm_clearance():
    for x0, y0 in ((1.5e-4, 0.0), (0.0, -2e-4), (1.1e-4, 1.1e-4)):
        rotor = {**TWO_MASS, "journal_x0": x0, "journal_y0": y0}
        u = units(rotor=("two_mass", rotor), bearing=("oilfilm", OILFILM))
        raises_param(["rotor.journal_x0", "clearance"], build_system, u)
    rotor = {**TWO_MASS, "journal_x0": 1.0e-4}
    build_system(units(rotor=("two_mass", rotor), bearing=("oilfilm", OILFILM)))


def test_oilfilm_needs_speed():
    u = units(rotor=("two_mass", {**TWO_MASS, "speed": 0.0}), bearing=("oilfilm", OILFILM))
    raises_param(["rotor.speed", "oil-film"], build_system, u)
    # a linear bearing does not need the speed
    build_system(units(rotor=("two_mass", {**TWO_MASS, "speed": 0.0}), bearing=("linear", LINEAR)))


@pytest.mark.parametrize("stop", ["rigid_two_sided", "elastic_two_sided"])
@pytest.mark.parametrize("barrier", [0.0, -0.5])
def test_two_sided_stop_needs_positive_barrier(stop, barrier):
    q = {**OSC, "stop": stop, "barrier": barrier, "stop_stiffness": 10.0}
    raises_param(
        ["oscillator.barrier", "> 0"], build_system, units(oscillator=("impact_oscillator", q))
    )


def test_one_sided_stop_allows_any_barrier():
    q = {**OSC, "stop": "rigid_one_sided", "barrier": -0.5, "x0": -1.0}
    build_system(units(oscillator=("impact_oscillator", q)))


@pytest.mark.parametrize("stop", ["elastic_one_sided", "elastic_two_sided"])
def test_elastic_stop_needs_stiffness(stop):
    q = {**OSC, "stop": stop, "stop_stiffness": 0.0}
    raises_param(
        ["oscillator.stop_stiffness", "> 0"],
        build_system,
        units(oscillator=("impact_oscillator", q)),
    )


def test_rigid_oscillator_starting_beyond_barrier():
    q = {**OSC, "x0": 1.5}  # default barrier 1, rigid one-sided
    raises_param(
        ["oscillator.x0", "barrier"], build_system, units(oscillator=("impact_oscillator", q))
    )
    q = {**OSC, "stop": "rigid_two_sided", "x0": -1.5}
    raises_param(
        ["oscillator.x0", "barrier"], build_system, units(oscillator=("impact_oscillator", q))
    )
    q = {**OSC, "stop": "elastic_one_sided", "stop_stiffness": 5.0, "x0": 1.5}
    build_system(units(oscillator=("impact_oscillator", q)))


def controller_system(speed=ROTOR["speed"], **given):
    rotor = {**ROTOR, "speed": speed}
    return units(
        rotor=("jeffcott", rotor), controller=("delayed_feedback", {**CONTROLLER, **given})
    )


def test_controller_modulation_amplitude_must_be_below_delay():
    raises_param(
        ["controller.modulation_amplitude", "delay"],
        build_system,
        controller_system(delay=0.01, modulation_amplitude=0.01),
    )
    raises_param(
        ["controller.modulation_amplitude", "delay"],
        build_system,
        controller_system(delay=0.01, modulation_amplitude=0.02),
    )
    build_system(controller_system(delay=0.01, modulation_amplitude=0.009))
    # with delay_periods: tau0 = 2 pi / w = 0.01656 s
    raises_param(
        ["controller.modulation_amplitude"],
        build_system,
        controller_system(modulation_amplitude=0.02),
    )


def test_controller_modulation_product_must_be_below_one():
    raises_param(
        ["controller.modulation_amplitude", "controller.modulation_frequency", "< 1"],
        build_system,
        controller_system(delay=0.01, modulation_amplitude=0.005, modulation_frequency=200.0),
    )
    raises_param(
        ["controller.modulation_frequency"],
        build_system,
        controller_system(delay=0.01, modulation_amplitude=0.005, modulation_frequency=300.0),
    )
    system = build_system(
        controller_system(delay=0.01, modulation_amplitude=0.005, modulation_frequency=150.0)
    )
    assert system.min_delay() == pytest.approx(0.005)


def test_controller_delay_must_be_positive():
    def negative_delay():
        return build_system(controller_system(delay=-0.01))

    raises_param(["controller.delay", "[0, inf]"], negative_delay)


def test_controller_delay_periods_needs_speed():
    raises_param(
        ["controller.delay_periods", "rotor.speed"], build_system, controller_system(speed=0.0)
    )
    system = build_system(controller_system(speed=0.0, delay=0.01))
    assert system.min_delay() == pytest.approx(0.01)


def test_controller_delay_from_periods():
    system = build_system(controller_system(delay_periods=3))
    assert system.min_delay() == pytest.approx(3 * 2 * math.pi / ROTOR["speed"])


def test_make_unit_unhashable_type():
    raises_param(["rotor.type"], make_unit, "rotor", ["jeffcott"], ROTOR)
