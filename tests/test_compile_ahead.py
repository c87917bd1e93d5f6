"""The engine compiled in a second process, against a model that stands still
(:mod:`rubcosim.reference.compile_ahead`, :mod:`rubcosim.reference.null_model`)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numba
import numpy as np

from rubcosim.reference import compile_ahead
from rubcosim.reference.null_model import null_model
from rubcosim.reference.simulate import _run
from rubcosim.reference.specialize import compiled_model
from rubcosim.scenario import load_scenario


def _system(name: str):
    return load_scenario(name).system


def test_the_null_model_has_the_type_of_every_models_tuple():
    """What makes the helper's cache entries the ones every model loads: numba types a
    model tuple by its kernels' signatures, and the null model's are the same."""
    for name in ("impact_oscillator_linear", "jeffcott_rigid_stator", "feng_yang_attractors"):
        system = _system(name)
        real = numba.typeof(tuple(compiled_model(system)))
        assert numba.typeof(tuple(null_model(system.ip))) == real


def test_an_engine_on_the_null_model_stands_still():
    """Wiring of the null model's kernels: both engines keep the initial state, record
    zeros and find no event (every array the kernels are given is filled)."""
    system = _system("jeffcott_rigid_stator")
    t_end = 20 * system.forcing_period
    t_eval = np.linspace(0.0, t_end, 11)
    tol = (1e-9, 1e-9 * system.state_scale, np.inf)
    for engine in ("fast", "accurate"):
        res = _run(system, null_model(system.ip), engine, 0.0, t_end, t_eval, tol, 16, 16)
        assert res.ok, res.message
        assert np.array_equal(res.final_state, system.y0)
        assert np.all(res.outputs == 0.0)
        assert res.counters["events"] == 0


_HELPER_HITS = textwrap.dedent(
    """
    import json
    from rubcosim.reference import compile_ahead, fast
    from rubcosim.scenario import load_scenario

    compile_ahead.compile_engine(load_scenario("jeffcott_rigid_stator").system, "fast")
    stats = fast.integrate.stats
    print(json.dumps({"hits": sum(stats.cache_hits.values()),
                      "misses": sum(stats.cache_misses.values())}))
    """
)


def test_the_helper_loads_the_entry_a_real_model_compiled():
    """The helper compiles nothing that a run of a real model put in the cache: in a
    fresh process, against the cache the test run shares (a real model ran the fast
    engine's delay-free variant there: the warm-up, or the test above), the null model's
    run of the fast engine is a cache hit and no miss."""
    env = {**os.environ, "RUBCOSIM_QUIET_COMPILE": "1"}
    out = subprocess.run(
        [sys.executable, "-c", _HELPER_HITS], capture_output=True, text=True, env=env, check=True
    )
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts == {"hits": 1, "misses": 0}


def test_a_marked_engine_starts_no_helper(tmp_path, monkeypatch):
    """The marker: once an engine variant is recorded in this cache, no helper starts;
    helpers can be turned off."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("RUBCOSIM_COMPILE_AHEAD", "1")
    system = _system("impact_oscillator_linear")
    assert not compile_ahead.is_compiled("fast", system.has_delay)
    compile_ahead.mark_compiled("fast", system.has_delay)
    assert compile_ahead.is_compiled("fast", system.has_delay)
    assert not compile_ahead.is_compiled("fast", not system.has_delay)
    assert compile_ahead.start(system, "fast") is None
    monkeypatch.setenv("RUBCOSIM_COMPILE_AHEAD", "0")
    assert compile_ahead.start(system, "accurate") is None
