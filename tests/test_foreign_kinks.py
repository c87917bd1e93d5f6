"""Kinks and jumps in a foreign FMU's output located as events (orchestrator.kink_steps):
the bouncing ball's height (a kink per bounce) or velocity (a jump per bounce) forcing
the impact oscillator, against scipy with the ball in closed form."""

from __future__ import annotations

import shutil
import sys
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rubcosim.orchestrator.assembly import run_cosim
from rubcosim.orchestrator.settings import SettingsError, cosim_settings
from rubcosim.scenario import build_scenario

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "foreign_fmu"
sys.path.insert(0, str(EXAMPLE))
from ball_reference import ball_state, driven_oscillator  # noqa: E402
from build import build  # noqa: E402


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("kinks")
    build(d / "bouncing_ball.fmu")
    shutil.copy(EXAMPLE / "oscillator_and_ball.toml", d)
    return d / "oscillator_and_ball.toml"


def driven_by(path: Path, field: str, kinks: str):
    data = tomllib.loads(path.read_text())
    data["connections"] = {"oscillator.force": [f"ball.{field}"]}
    sc = build_scenario(data, source=str(path))
    return run_cosim(sc, settings=replace(sc.cosim, kinks=kinks))


def test_the_reference_ball_is_the_fmus_ball(scenario_dir):
    # the closed form the reference uses against the FMU's own output
    r = driven_by(scenario_dir, "h", "locate")
    assert r.ok, r.message
    h = np.array([ball_state(t, 1.0, 0.7)[0] for t in r.t])
    v = np.array([ball_state(t, 1.0, 0.7)[1] for t in r.t])
    assert np.max(np.abs(r.output("ball.h") - h)) < 1e-12
    assert np.max(np.abs(r.output("ball.v") - v)) < 1e-9


@pytest.mark.parametrize("field, tol", [("h", 1e-9), ("v", 1e-7)])
def test_kinks_and_jumps_of_a_foreign_output_are_located_not_rejected(scenario_dir, field, tol):
    located = driven_by(scenario_dir, field, "locate")
    plain = driven_by(scenario_dir, field, "off")
    assert located.ok and plain.ok, located.message + plain.message
    x_ref = driven_oscillator(located.t, field=field)
    for r in (located, plain):
        assert np.max(np.abs(r.output("oscillator.x") - x_ref)) < tol
    c, c0 = located.counters, plain.counters
    # the ball bounces about 20 times with a kink the coupling tolerance resolves
    assert c["kinks"] >= 15 and "kinks" not in c0
    # error control alone rejects a third of its steps or more; located, under a tenth
    assert c0["rejected"] > 0.3 * c0["accepted"]
    assert c.get("rejected", 0) < 0.1 * c["accepted"]
    assert c["unit_steps"] < c0["unit_steps"]


def test_the_kinks_setting_names_its_key():
    assert cosim_settings({"kinks": "off"}).kinks == "off"
    with pytest.raises(SettingsError, match="cosim.kinks = 'maybe' is not one of locate, off"):
        cosim_settings({"kinks": "maybe"})
