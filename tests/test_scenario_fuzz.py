"""Scenario files fuzzed (issue 49): one field of a bundled scenario replaced by a wrong
value, removed, or joined by an unknown key.  Loading either gives a valid scenario or
one ``ValueError`` (``ScenarioError``, ``ParameterError``, ``SettingsError``,
``CouplingError``) whose message names the field; never another exception."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from rubcosim import api

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
NAMES = sorted(p.stem for p in SCENARIOS.glob("*.toml"))
TABLES = {n: tomllib.loads((SCENARIOS / f"{n}.toml").read_text()) for n in NAMES}

# Fields the exhaustive pass (every leaf of every bundled scenario with every value of
# BAD_VALUES' first strategy, 2026-11-28) found not named, or not refused cleanly; each
# is held by test_the_fields_the_exhaustive_pass_found below.
FOUND = {
    ("units", "stator", "x_offset"): ("jeffcott_offset_rigid_stator", -1.0),  # named x0/y0
    ("units", "stator", "y_offset"): ("jeffcott_offset_rigid_stator", -1.0),  # named x0/y0
    ("units", "bearing", "radius"): ("two_mass_oilfilm_rub", 1e300),  # OverflowError
    ("units", "bearing", "length"): ("two_mass_oilfilm_rub", 1e300),  # OverflowError
    ("sim", "t_end"): ("impact_duffing", 1e300),  # named only sim.output_step
}

BAD_VALUES = st.one_of(
    st.sampled_from([-1.0, 0.0, -1e300, 1e300, math.nan, math.inf, -math.inf, -1, 0]),
    st.sampled_from(["", "fast!", "1e-3x", "nan"]),
    st.booleans(),
    st.lists(st.floats(allow_nan=True), max_size=3),
    st.dictionaries(st.sampled_from(["a", "b"]), st.integers(), max_size=2),
)


def _leaves(table: dict, prefix: tuple = ()) -> list[tuple]:
    out = []
    for key, value in table.items():
        if isinstance(value, dict):
            out.extend(_leaves(value, (*prefix, key)))
        else:
            out.append((*prefix, key))
    return out


@st.composite
def mutated(draw):
    """(scenario name, mutated table, the path changed)."""
    name = draw(st.sampled_from(NAMES))
    table = copy.deepcopy(TABLES[name])
    leaves = [p for p in _leaves(table) if p[0] not in ("scenario", "plots")]
    path = draw(st.sampled_from(leaves))
    parent = table
    for key in path[:-1]:
        parent = parent[key]
    action = draw(st.sampled_from(["replace", "remove", "unknown"]))
    if action == "remove":
        del parent[path[-1]]
    elif action == "unknown":
        path = (*path[:-1], "no_such_field")
        parent["no_such_field"] = 1.0
    else:
        parent[path[-1]] = draw(BAD_VALUES)
    return name, table, path


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_a_fuzzed_scenario_loads_or_gives_one_error_naming_the_field(case):
    name, table, path = case
    _loads_or_names(name, table, path)


def _loads_or_names(name: str, table: dict, path: tuple) -> None:
    try:
        api.load(table)
    except ValueError as exc:
        event("refused")
        message = str(exc)
        assert path[-1] in message, f"{name}: {'.'.join(map(str, path))} -> {message!r}"
    else:
        event("accepted")


@pytest.mark.parametrize("path", sorted(FOUND), ids=".".join)
def test_the_fields_the_exhaustive_pass_found(path):
    name, value = FOUND[path]
    table = copy.deepcopy(TABLES[name])
    parent = table
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = value
    with pytest.raises(ValueError) as refused:
        api.load(table)
    assert path[-1] in str(refused.value)
