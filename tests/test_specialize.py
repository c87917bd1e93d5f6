"""Per-model compiled modules (``rubcosim/reference/specialize.py``): what a copy holds,
which models share one, that a second process compiles nothing, and the compile notice."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np
import pytest

from rubcosim.reference import system as S
from rubcosim.reference.model_calls import events, outputs
from rubcosim.reference.specialize import MODEL_MODULES, model_key, model_label, specialized
from rubcosim.reference.system_outputs import outputs as system_outputs
from rubcosim.scenario import load_scenario


def _system(name: str, overrides: list[str] | None = None):
    return load_scenario(name, overrides or []).system


def _source_of(module) -> str:
    with open(module.__file__) as f:
        return f.read()


@pytest.fixture
def family_scope(monkeypatch):
    """The default scope, whatever the environment says."""
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "family")


def test_a_copy_reads_its_family_as_constants(family_scope):
    """Wiring, family scope (the default): the rigid stator's copy of the system reads
    its family and its controller as constants of the model, the rest from ``ip``."""
    system = _system("jeffcott_rigid_stator")
    copy = specialized("rubcosim.reference.system", system.ip)
    source = _source_of(copy)
    assert "ip[IP_FAMILY]" not in source and "ip[IP_CONTROLLER]" not in source
    assert "ip[IP_STATOR]" in source
    assert copy.M_IP_FAMILY == S.FAMILY_ROTOR and copy.M_IP_CONTROLLER == S.CONTROLLER_NONE
    assert not hasattr(copy, "M_IP_STATOR")


def test_in_model_scope_a_copy_reads_the_models_structure_as_constants(monkeypatch):
    """Wiring, model scope: every structural read of ``ip`` is a constant of the model,
    and the constants are that model's; a choice stays a run-time read."""
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "model")
    system = _system("jeffcott_rigid_stator")
    copy = specialized("rubcosim.reference.system", system.ip)
    source = _source_of(copy)
    assert "ip[IP_STATOR]" not in source and "ip[IP_FAMILY]" not in source
    assert copy.M_IP_STATOR == S.STATOR_RIGID == system.ip[S.IP_STATOR]
    assert copy.M_IP_STATOR_CASING_X == -1
    assert "ip[IP_CONTROLLER_FEEDBACK]" in source
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "everything")
    with pytest.raises(ValueError, match="RUBCOSIM_COMPILE_SCOPE = 'everything'"):
        specialized("rubcosim.reference.system", system.ip)


def test_the_kernels_copy_imports_the_systems_copy_and_nothing_else_is_copied(family_scope):
    """Wiring: a model's C functions are compiled from its copy of the system; the
    engines' machinery is not copied (one compilation serves every model)."""
    system = _system("impact_duffing")
    kernels = specialized("rubcosim.reference.model_kernels", system.ip)
    copy = specialized("rubcosim.reference.system", system.ip)
    assert kernels.rhs_c._pyfunc.__globals__["rhs"] is copy.rhs
    names = ("rhs_c", "events_c", "apply_c", "outputs_c", "step_c", "dense_c")
    assert tuple(getattr(kernels, name) for name in names) == kernels.KERNELS
    for machinery in ("rubcosim.reference.fast", "rubcosim.analysis.strobe_kernels"):
        with pytest.raises(ValueError, match="does not depend on the model"):
            specialized(machinery, system.ip)
    assert len(MODEL_MODULES) == len(set(MODEL_MODULES))


def test_which_models_share_their_kernels(monkeypatch):
    """Wiring: a parameter or a choice (the modulation shape) never gives other kernels;
    in family scope a stator type does not either, a controller does; in model scope
    both do."""
    rigid = _system("jeffcott_rigid_stator")
    other_speed = _system("jeffcott_rigid_stator", ["rotor.speed=400"])
    elastic = _system("jeffcott_elastic_stator")
    controlled = _system("jeffcott_delayed_feedback")
    sine = _system("jeffcott_delayed_feedback", ["controller.modulation_shape=sine"])
    saw = _system("jeffcott_delayed_feedback", ["controller.modulation_shape=sawtooth"])
    assert not np.array_equal(sine.ip, saw.ip)
    oscillator, two_dof = _system("impact_duffing"), _system("two_dof_impact_oscillator")
    for scope in ("family", "model"):
        monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", scope)
        assert model_key(rigid.ip) == model_key(other_speed.ip)
        assert model_key(sine.ip) == model_key(saw.ip)
        assert model_key(rigid.ip) != model_key(controlled.ip)
        assert model_key(oscillator.ip) != model_key(two_dof.ip)
        same_stator_kernels = model_key(rigid.ip) == model_key(elastic.ip)
        assert same_stator_kernels == (scope == "family")
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "family")
    a = specialized("rubcosim.reference.model_kernels", sine.ip)
    assert a is specialized("rubcosim.reference.model_kernels", saw.ip)
    assert a is not specialized("rubcosim.reference.model_kernels", rigid.ip)


def test_model_label_names_the_units():
    assert model_label(_system("jeffcott_rigid_stator")) == "rotor.jeffcott + stator.rigid"
    assert model_label(_system("impact_duffing")) == "oscillator.impact_oscillator"


_SECOND_RUN = textwrap.dedent(
    """
    import json, sys
    from numba.core import event
    compiled = []

    class Count(event.Listener):
        def on_start(self, ev):
            compiled.append(ev.data["dispatcher"].py_func.__qualname__)

        def on_end(self, ev):
            pass

    import rubcosim as rc
    from rubcosim.reference.specialize import compiled_model
    with event.install_listener("numba:compile", Count()):
        res = rc.simulate("impact_oscillator_linear", "fast", set={"sim.t_end": 5.0})
    # C functions compile without numba's compile events: their cache hits tell
    kernels = compiled_model(rc.load("impact_oscillator_linear").system)[1:]
    loaded = [k.cache_hits for k in kernels]
    print(json.dumps({"ok": res.ok, "compiled": compiled, "kernels_loaded": loaded}))
    """
)


def _fresh_process() -> dict:
    # family scope, the default: the copies written by one process, found by the next
    env = {**os.environ, "RUBCOSIM_QUIET_COMPILE": "1", "RUBCOSIM_COMPILE_SCOPE": "family"}
    out = subprocess.run(
        [sys.executable, "-c", _SECOND_RUN], capture_output=True, text=True, env=env, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_second_process_of_a_scenario_compiles_nothing():
    """Caching across processes: a fresh process that runs a scenario whose engine is in
    numba's cache (the first one here put it there, if the cache was cold) starts no
    numba compilation at all, and loads the model's six C functions from the cache."""
    first = _fresh_process()
    second = _fresh_process()
    assert first["ok"] and second["ok"]
    assert second["compiled"] == []
    assert second["kernels_loaded"] == [1] * 6


def test_a_compilation_is_announced_once_with_its_time(capsys):
    """The notice: one line naming what compiles, one with its time; nothing when the
    block compiles nothing."""
    from rubcosim.compile_notice import announce

    @numba.njit  # not cached: compiled in this process
    def fresh(x):
        return x + 1.0

    with announce("a test kernel"):
        fresh(1.0)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("rubcosim: compiling a test kernel (first use")
    assert err[1].startswith("rubcosim: compiled a test kernel in ")
    assert len(err) == 2
    with announce("a test kernel"):
        fresh(2.0)  # compiled already
    assert capsys.readouterr().err == ""


@numba.njit
def _through_the_pointers(model, t, y, yd, mode, p, g, dirs, rates, out):  # pragma: no cover
    """The events and outputs as the engines call them (:mod:`.model_calls`)."""
    events(t, y, yd, mode, p, model, g, dirs, rates)
    outputs(t, y, yd, mode, p, model, out)


def _kernel_values(system, rng: np.random.Generator, copied: bool) -> list[np.ndarray]:
    """The right-hand side, the event functions and the outputs of ``system`` at a few
    states around its initial one, in each of its first three modes (a delay-free
    model: no history): through the model's C functions (``copied``), or by the
    package's own :mod:`.system`, which branches on ``ip`` at run time."""
    from rubcosim.reference import history
    from rubcosim.reference.specialize import compiled_model

    p, ip = np.array(system.p, dtype=float), np.array(system.ip, dtype=np.int64)
    model = compiled_model(system)
    yd = np.zeros(S.N_DELAYED)
    values = []
    for _ in range(3):
        y = system.y0 + 0.1 * system.state_scale * rng.standard_normal(system.n_state)
        for mode in range(3):
            g = np.zeros(S.N_EVENTS)
            dirs, rates = np.zeros(S.N_EVENTS, np.int64), np.zeros(S.N_EVENTS, np.int64)
            out = np.zeros(len(system.output_names))
            if copied:
                values.append(history.full_rhs_alloc(0.01, y, mode, p, model, None))
                _through_the_pointers(model, 0.01, y, yd, mode, p, g, dirs, rates, out)
            else:
                dy = np.empty_like(y)
                S.rhs(0.01, y, yd, mode, p, ip, dy)
                values.append(dy)
                S.events(0.01, y, yd, mode, p, ip, g, dirs, rates)
                system_outputs(0.01, y, yd, mode, p, ip, out)
            values += [g, dirs.astype(float), rates.astype(float), out]
    return values


# one test, not one per model: the package's own kernels (every branch) compile once
COPIED = ("jeffcott_rigid_stator", "jeffcott_offset_rigid_stator", "jeffcott_elastic_stator",
          "jeffcott_elastic_casing", "two_mass_oilfilm_rub", "impact_duffing",
          "two_dof_impact_oscillator")  # fmt: skip


def test_a_copy_computes_what_the_modules_it_was_copied_from_compute(family_scope):
    """Second compilation of the same kernels: a family's C functions (compiled from its
    copy of the system, family scope) called through the engines' pointers, and the
    package's own system (which branches on ``ip`` at run time) give the same
    right-hand side, event functions and outputs, bit for bit, on every bundled
    delay-free model."""
    for name in COPIED:
        system = _system(name)
        ours = _kernel_values(system, np.random.default_rng(7), copied=True)
        theirs = _kernel_values(system, np.random.default_rng(7), copied=False)
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_array_equal(a, b, err_msg=name)


def test_the_kernels_label_says_what_the_engine_serves(monkeypatch):
    """Wiring: the compile notice names the family the kernels serve, not only the model."""
    from rubcosim.reference.specialize import kernels_label

    rigid, duffing = _system("jeffcott_rigid_stator"), _system("impact_duffing")
    controlled = _system("jeffcott_delayed_feedback")
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "family")
    assert kernels_label(rigid) == (
        "the rotor family without a controller (here rotor.jeffcott + stator.rigid)"
    )
    assert kernels_label(controlled).startswith("the rotor family with the delayed-feedback")
    assert kernels_label(duffing) == "oscillator.impact_oscillator"
    monkeypatch.setenv("RUBCOSIM_COMPILE_SCOPE", "model")
    assert kernels_label(rigid) == "rotor.jeffcott + stator.rigid"
