"""The FMUs: built, valid, rollback-safe, robust, and equal to the units they wrap."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from fmpy.validation import validate_fmu

from rubcosim.cli import main
from rubcosim.components.rotor import free_whirl
from rubcosim.components.unit import StepError
from rubcosim.components.units import UNIT_CLASSES
from rubcosim.fmus.build import MODEL_IDENTIFIERS, BuildRequestError, build_fmus, fmu_specs
from rubcosim.orchestrator.fmu_unit import FmuError, FmuUnit

from test_units import KEY_OF, STIMULI, run, step_size, stimulus

IDENTIFIERS = sorted(MODEL_IDENTIFIERS.values())
PYTHON = sys.executable


def step_of(ident: str) -> float:
    return step_size(KEY_OF[ident][0])


def stimulus_params(ident: str) -> dict:
    return STIMULI[KEY_OF[ident]][0]


def test_every_unit_has_an_fmu(built_fmus):
    assert set(MODEL_IDENTIFIERS) == set(UNIT_CLASSES)
    assert sorted(built_fmus) == IDENTIFIERS
    assert [s.identifier for s in fmu_specs()] == [MODEL_IDENTIFIERS[k] for k in UNIT_CLASSES]


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_fmu_validates_and_describes_every_variable(built_fmus, ident):
    path = built_fmus[ident]
    assert validate_fmu(str(path)) == []
    with zipfile.ZipFile(path) as z:
        root = ET.fromstring(z.read("modelDescription.xml"))
        names = z.namelist()
        sources = [z.read(n).decode() for n in names if n.endswith(".py")]
    units = {u.get("name") for u in root.iter("Unit")}
    cls = UNIT_CLASSES[KEY_OF[ident]]
    declared = {p.name: p for p in cls.params_spec}
    signals = {s.name: s for s in (*cls.inputs, *cls.outputs)}
    carriers = {f"{s.name}_d{k}": s for s in cls.inputs if s.kind == "real" for k in (1, 2)}
    for sv in root.iter("ScalarVariable"):
        name, causality = sv.get("name"), sv.get("causality")
        assert sv.get("description"), name
        if name in carriers:  # an input's derivative, set by fmi2SetRealInputDerivatives
            assert (causality, sv.get("variability")) == ("parameter", "tunable"), name
            expected_unit = ""
        elif causality == "parameter":
            assert sv.get("variability") == "fixed"
            expected_unit = declared[name].unit
        else:
            sig = signals[name]
            expected_unit = sig.unit
            want = "discrete" if sig.kind == "integer" else "continuous"
            assert sv.get("variability") == want, name
            if causality == "output":
                assert sv.get("initial") == "exact"
        real = sv.find("Real")
        if real is not None and expected_unit:
            assert real.get("unit") == expected_unit and expected_unit in units, name
    cs = root.find("CoSimulation")
    assert cs.get("canGetAndSetFMUstate") == "true" and cs.get("canSerializeFMUstate") == "true"
    assert cs.get("canInterpolateInputs") == "true"
    table = z_read(path, "resources/rubcosim_input_derivatives.txt").split()
    assert len(table) == 3 * len(carriers)
    assert root.get("description", "").startswith(cls.summary)
    if cls.protocol:
        assert "reset_counter" in root.get("description")
    # the FMU carries its own code: nothing in it imports the rubcosim package
    assert not any(re.search(r"^\s*(from|import) rubcosim[\s.]", s, re.M) for s in sources)
    assert f"binaries/linux64/{ident}.so" in names
    assert f"binaries/linux64/{ident}_pythonfmu_export.so" in names


def z_read(path, name: str) -> str:
    with zipfile.ZipFile(path) as z:
        return z.read(name).decode()


def test_input_derivatives_reach_the_unit_through_the_loader(built_fmus):
    # a free mass pushed by f = a + b t + c t^2 / 2 over one step, set as value + derivatives:
    # x = a t^2 / 2m + b t^3 / 6m + c t^4 / 24m
    m, a, b, c, t = 2.0, 3.0, 40.0, 100.0, 0.5
    params = dict(mass=m, damping=0.0, stiffness=1e-30, eccentricity=0.0, speed=0.0)
    with FmuUnit(built_fmus["RubcosimJeffcottRotor"], params=params) as fmu:
        assert fmu.md.coSimulation.canInterpolateInputs
        fmu.set_input_polynomial("fx", a, b, c)
        fmu.do_step(0.0, t)
        x = fmu.get_outputs()["x"]
        with pytest.raises(FmuError, match="fmi2SetRealInputDerivatives"):
            fmu.set_input_polynomial("reset_counter", 0, 1.0, 0.0)  # an integer: none
    want = a * t**2 / (2 * m) + b * t**3 / (6 * m) + c * t**4 / (24 * m)
    assert x == pytest.approx(want, rel=1e-9)


def test_derivatives_of_several_inputs_in_one_call_reach_each_input(built_fmus):
    # the loader sets all the carriers of one fmi2SetRealInputDerivatives in one fmi2SetReal:
    # each input must get its own derivatives (x from fx's polynomial, y from fy's)
    m, t = 2.0, 0.5
    params = dict(mass=m, damping=0.0, stiffness=1e-30, eccentricity=0.0, speed=0.0)
    fx, fy = (3.0, 40.0, 100.0), (-1.0, 7.0, -60.0)
    with FmuUnit(built_fmus["RubcosimJeffcottRotor"], params=params) as fmu:
        fmu.set_input_polynomials({"fx": fx, "fy": fy})
        fmu.do_step(0.0, t)
        out = fmu.get_outputs()

    def drift(a: float, b: float, c: float) -> float:
        return a * t**2 / (2 * m) + b * t**3 / (6 * m) + c * t**4 / (24 * m)

    assert out["x"] == pytest.approx(drift(*fx), rel=1e-9)
    assert out["y"] == pytest.approx(drift(*fy), rel=1e-9)


def test_builds_are_reproducible(tmp_path):
    a = build_fmus(tmp_path / "a", only=["RubcosimLinearBearing"])[0]
    b = build_fmus(tmp_path / "b", only=["RubcosimLinearBearing"])[0]
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_fmu_state_restore_and_serialisation_are_bit_identical(built_fmus, ident):
    _, inputs = stimulus(KEY_OF[ident])
    h = step_of(ident)
    with FmuUnit(built_fmus[ident], params=stimulus_params(ident)) as fmu:
        run(fmu, inputs, 0.0, 5, h)
        state = fmu.get_state()
        first = run(fmu, inputs, 5 * h, 5, h)
        fmu.set_state(state)
        again = run(fmu, inputs, 5 * h, 5, h)
        fmu.set_state(state)  # the same snapshot twice
        third = run(fmu, inputs, 5 * h, 5, h)
        data = fmu.serialize_state(state)
        fmu.free_state(state)
        restored = fmu.deserialize_state(data)
        fmu.set_state(restored)
        fourth = run(fmu, inputs, 5 * h, 5, h)
        fmu.free_state(restored)
    assert first == again == third == fourth
    assert any(v != 0 for o in first for v in o.values())


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_fmu_matches_the_unit_it_wraps(built_fmus, ident):
    key = KEY_OF[ident]
    params, inputs = stimulus(key)
    h = step_of(ident)
    unit = UNIT_CLASSES[key](**params)
    with FmuUnit(built_fmus[ident], params=stimulus_params(ident)) as fmu:
        got = run(fmu, inputs, 0.0, 10, h)
    want = run(unit, inputs, 0.0, 10, h)
    # the same code; the FMU runs the kernels as plain Python, the unit compiled by numba,
    # so the last bit may differ; and a unit with a continuous state is integrated by
    # scipy's DOP853 in the FMU, by the compiled one in-process: the same method at the same
    # tolerance (unit rtol 1e-10), but not the same step sequence
    rel = 1e-9 if "y" in unit.state else 1e-12
    for g, w in zip(got, want, strict=True):
        assert g == pytest.approx(w, rel=rel, abs=1e-300)


REFUSED = """import sys
from rubcosim.orchestrator.fmu_unit import FmuError, FmuUnit
try:
    FmuUnit(sys.argv[1], params={sys.argv[2]: float(sys.argv[3])})
except FmuError as exc:
    print("FmuError:", exc)
"""


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_invalid_parameter_is_refused_at_initialisation(built_fmus, ident, tmp_path):
    # In a process of its own: the FMU refuses it through pythonfmu's exception path
    # (fmi2Fatal, tests/test_fmi_sequences.py), which drops references it does not own,
    # and a later instance of the same FMU in the same process can then fail or crash.
    cls = UNIT_CLASSES[KEY_OF[ident]]
    p = next(p for p in cls.params_spec if p.kind == "real" and math.isfinite(p.low))
    bad = p.low - 1.0
    proc = subprocess.run(
        [PYTHON, "-c", REFUSED, str(built_fmus[ident]), p.name, repr(bad)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, check=False,
    )  # fmt: skip
    assert re.search(rf"^FmuError: .*{cls.role}\.{p.name}", proc.stdout, re.M), (
        proc.stdout + proc.stderr[-2000:]
    )


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_a_failing_step_is_reported_and_leaves_the_state(built_fmus, ident):
    _, inputs = stimulus(KEY_OF[ident])
    h = step_of(ident)
    cls = UNIT_CLASSES[KEY_OF[ident]]
    name = next(s.name for s in cls.inputs if s.kind == "real")
    with FmuUnit(built_fmus[ident], params=stimulus_params(ident)) as fmu:
        run(fmu, inputs, 0.0, 3, h)
        before = fmu.serialize_state(fmu.get_state())
        fmu.set_input(name, math.nan)
        with pytest.raises(StepError, match=rf"input {name} = nan is not finite"):
            fmu.do_step(3 * h, h)
        fmu.set_inputs(inputs(3 * h))
        after = fmu.serialize_state(fmu.get_state())
        strip = [json.loads(x) for x in (before, after)]
        for s in strip:
            s.pop("u")
        assert strip[0] == strip[1]
        fmu.do_step(3 * h, h)  # it goes on from where it was


def test_every_fmu_loads_together_in_one_process(built_fmus):
    units = [FmuUnit(path, name=f"u{i}") for i, path in enumerate(built_fmus.values())]
    units.append(FmuUnit(built_fmus["RubcosimJeffcottRotor"], name="second_rotor"))
    try:
        for u in units:
            u.do_step(0.0, 1e-4)
            assert all(np.isfinite(v) for v in u.get_outputs().values())
    finally:
        for u in units:
            u.close()
    # and again after all were freed
    with FmuUnit(built_fmus["RubcosimJeffcottRotor"]) as again:
        again.do_step(0.0, 1e-4)


def test_missing_or_broken_fmu_is_a_clear_error(tmp_path):
    with pytest.raises(FmuError, match="FMU not found"):
        FmuUnit(tmp_path / "nope.fmu")
    junk = tmp_path / "junk.fmu"
    junk.write_bytes(b"not a zip")
    with pytest.raises(FmuError, match="not a readable FMU"):
        FmuUnit(junk)


FRESH = r"""
import json, sys
import fmpy
ident, path, stop, step = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
start = json.loads(sys.argv[5])
if len(sys.argv) > 6 and sys.argv[6] == "no-numba":
    sys.modules["numba"] = None  # as on a machine without numba
res = fmpy.simulate_fmu(path, stop_time=stop, output_interval=step, start_values=start)
names = [n for n in res.dtype.names if n != "time"]
# numba's cache misses in this process: the bundle's kernels compiled here, not loaded
misses = sum(len(f.stats.cache_misses) for m in list(sys.modules.values())
             if getattr(m, "__name__", "").startswith("rubcosim_")
             for f in vars(m).values() if hasattr(f, "stats"))
print(json.dumps({"rows": len(res), "last": [float(res[n][-1]) for n in names],
                  "rubcosim_imported": any(m.startswith("rubcosim.") for m in sys.modules),
                  "numba": "numba" in sys.modules and sys.modules["numba"] is not None,
                  "misses": misses}))
"""


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_fmu_simulates_with_fmpy_in_a_fresh_process(built_fmus, ident, tmp_path):
    h = step_of(ident)
    proc = subprocess.run(
        [PYTHON, "-c", FRESH, ident, str(built_fmus[ident]), repr(20 * h), repr(h),
         json.dumps(stimulus_params(ident))],
        capture_output=True, text=True, timeout=120, cwd=tmp_path, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["rows"] == 21 and all(math.isfinite(v) for v in out["last"])
    assert not out["rubcosim_imported"]


def test_fmu_runs_without_numba_and_with_it(built_fmus, tmp_path):
    path = str(built_fmus["RubcosimImpactOscillator"])
    start = json.dumps(stimulus_params("RubcosimImpactOscillator"))
    # bundle copies of other builds: one unused for 40 days (removed), one used today
    bundles = tmp_path / "cache" / "rubcosim" / "fmu_bundles"
    stale, recent = bundles / "rubcosim_bundle_stale", bundles / "rubcosim_bundle_recent"
    for folder in (stale / "pkg", recent / "pkg"):
        folder.mkdir(parents=True)
    forty_days_ago = time.time() - 40 * 86400.0
    os.utime(stale, (forty_days_ago, forty_days_ago))
    results = []
    for env, extra in (
        ({}, []),
        ({"RUBCOSIM_NUMBA": "1"}, []),
        ({"RUBCOSIM_NUMBA": "1"}, ["no-numba"]),
        ({"RUBCOSIM_NUMBA": "1"}, []),  # a second load: from numba's cache
    ):
        proc = subprocess.run(
            [PYTHON, "-c", FRESH, "osc", path, "2.0", "0.05", start, *extra],
            capture_output=True, text=True, timeout=180, cwd=tmp_path, check=False,
            env={**os.environ, **env, "XDG_CACHE_HOME": str(tmp_path / "cache")},
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr[-2000:]
        results.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    assert [r["numba"] for r in results] == [False, True, False, True]
    assert results[1]["misses"] > 0  # an empty cache: the first load compiles
    assert results[0]["last"] == pytest.approx(results[1]["last"], rel=1e-12)
    assert results[0]["last"] == results[2]["last"]
    # the bundle is imported from a copy named by its sources' hash (fmus/build.py), so
    # numba finds what the first load compiled although fmpy unpacks to a new folder
    assert results[3]["last"] == results[1]["last"] and results[3]["misses"] == 0
    assert not stale.exists() and recent.is_dir()
    assert any(p.name.startswith("rubcosim_rubcosimimpactoscillator_") for p in bundles.iterdir())


def test_rotor_fmu_with_no_force_follows_the_free_whirl(built_fmus):
    m, c, k, e, w = 10.0, 316.227766, 1e6, 5e-5, 379.473319
    A, phase = free_whirl(m, c, k, e, w)
    x0, y0 = A * math.cos(-phase), A * math.sin(-phase)
    params = dict(mass=m, damping=c, stiffness=k, eccentricity=e, speed=w, x0=x0, y0=y0,
                  vx0=-w * y0, vy0=w * x0)  # fmt: skip
    h = 2 * math.pi / w / 32
    worst = 0.0
    with FmuUnit(built_fmus["RubcosimJeffcottRotor"], params=params) as fmu:
        for i in range(160):
            fmu.do_step(i * h, h)
            t = (i + 1) * h
            o = fmu.get_outputs()
            worst = max(worst, math.hypot(o["x"] - A * math.cos(w * t - phase),
                                          o["y"] - A * math.sin(w * t - phase)))  # fmt: skip
    assert worst < 1e-8 * A


def test_oscillator_fmu_matches_the_reference_engine(built_fmus):
    from rubcosim.reference import build_system, make_unit, simulate

    params = dict(linear_stiffness=1.0, damping=0.1, cubic_stiffness=1.0, forcing_amplitude=1.0,
                  forcing_frequency=2.0, barrier=1.0, restitution=0.8, x0=-2.0)  # fmt: skip
    h = math.pi / 16
    times = h * np.arange(0, 161)
    system = build_system({"oscillator": make_unit("oscillator", "impact_oscillator", params)})
    ref = simulate(system, float(times[-1]), t_eval=times, engine="fast", rtol=1e-12, atol=1e-14)
    xs = []
    with FmuUnit(built_fmus["RubcosimImpactOscillator"], params=params) as fmu:
        for i in range(160):
            fmu.do_step(i * h, h)
            xs.append(fmu.get_outputs()["x"])
        assert fmu.get_outputs()["impacts"] == ref.counters["impacts"]
    assert np.max(np.abs(np.array(xs) - ref.output("oscillator.x")[1:])) < 1e-7


def test_build_fmus_command(tmp_path, capsys):
    assert main(["build-fmus", "--out", str(tmp_path / "o"), "--only", "RubcosimRigidStator"]) == 0
    assert (tmp_path / "o" / "RubcosimRigidStator.fmu").is_file()
    assert capsys.readouterr().out.strip().endswith("RubcosimRigidStator.fmu")


def test_build_fmus_into_a_folder_that_cannot_be_made_is_one_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")  # a file where the output folder's parent should be
    out = blocker / "fmus"
    assert main(["build-fmus", "--out", str(out), "--only", "RubcosimRigidStator"]) != 0
    err = capsys.readouterr().err
    assert f"--out {out}: cannot create it" in err and "Traceback" not in err
    assert main(["build-fmus", "--out", str(tmp_path / "p"), "--only", "Nope"]) == 2
    assert "unknown FMU 'Nope'" in capsys.readouterr().err
    (tmp_path / "file").write_text("x")
    assert main(["build-fmus", "--out", str(tmp_path / "file")]) == 2
    assert "not a directory" in capsys.readouterr().err
    with pytest.raises(BuildRequestError):
        build_fmus(tmp_path / "q", only=["Nope"])


def test_building_after_loading_an_fmu_in_the_same_process(built_fmus, tmp_path):
    # a loaded pythonfmu FMU must not shadow the installed pythonfmu that builds FMUs
    code = (
        "import sys\n"
        "from pathlib import Path\n"
        "from rubcosim.orchestrator.fmu_unit import FmuUnit\n"
        "from rubcosim.fmus.build import build_fmus\n"
        "FmuUnit(sys.argv[1]).close()\n"
        "print(build_fmus(Path(sys.argv[2]), only=['RubcosimLinearBearing'])[0])\n"
    )
    proc = subprocess.run(
        [PYTHON, "-c", code, str(built_fmus["RubcosimLinearBearing"]), str(tmp_path)],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "RubcosimLinearBearing.fmu").is_file()


def _slave(path, name: str):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)  # fmt: skip
    fmu.instantiate()
    return fmu, {v.name: v.valueReference for v in md.modelVariables}


def test_a_state_restored_right_after_instantiation_is_where_the_next_step_starts(built_fmus):
    # fmusim --initial-fmu-state-file: instantiate, (start values,) fmi2DeSerializeFMUstate,
    # fmi2SetFMUstate, fmi2DoStep, with no initialisation mode in between
    from fmpy.fmi1 import FMICallException

    path = built_fmus["RubcosimJeffcottRotor"]
    a, vr = _slave(path, "a")
    a.setReal([vr["eccentricity"], vr["damping"]], [5e-5, 316.2])
    a.setupExperiment(startTime=0.0)
    a.enterInitializationMode()
    a.exitInitializationMode()
    t, h = 0.0, 0.0025
    for _ in range(20):
        a.doStep(t, h)
        t += h
    blob = a.serializeFMUstate(a.getFMUstate())
    a.doStep(t, h)
    want = a.getReal([vr["x"], vr["vx"]])
    for start_values in (False, True):
        b, _ = _slave(path, "b")
        if start_values:  # the same values, set before the restore
            b.setReal([vr["eccentricity"], vr["damping"]], [5e-5, 316.2])
        b.setFMUstate(b.deSerializeFMUstate(blob))
        b.doStep(t, h)
        assert b.getReal([vr["x"], vr["vx"]]) == want  # bit for bit
        # a step from a time the FMU is not at fails, and changes nothing
        with pytest.raises(FMICallException, match="fmi2DoStep"):
            b.doStep(0.0, h)
        assert b.getReal([vr["x"], vr["vx"]]) == want
        # after the restore: the same value again is fine; another is refused (the restored
        # state was computed with the old one) and changes nothing
        b.setReal([vr["damping"]], [316.2])
        b.doStep(t + h, h)
        after = b.getReal([vr["x"], vr["vx"]])
        with pytest.raises(FMICallException, match="fmi2SetReal"):
            b.setReal([vr["damping"]], [100.0])
        assert b.getReal([vr["damping"]]) == [316.2]
        assert b.getReal([vr["x"], vr["vx"]]) == after
        b.terminate()
        b.freeInstance()
    a.terminate()
    a.freeInstance()


def test_a_wrongly_typed_call_is_refused_with_an_error_and_the_instance_goes_on(built_fmus, capfd):
    """FMI 2.0: a caller's mistake (fmi2SetReal on an Integer variable, as cofmupy 1.0 sets
    the rotor's reset_counter; a reference no variable has) is fmi2Error with a logged
    message, never fmi2Fatal (which pythonfmu answered, dropping the instance): the
    loader checks the types before pythonfmu sees the call.  The instance then steps on
    and gives what an instance that never saw the call gives."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Error

    path = built_fmus["RubcosimJeffcottRotor"]
    runs = []
    for wrong_calls in (False, True):
        fmu, vr = _slave(path, f"typed{int(wrong_calls)}")
        fmu.setReal([vr["eccentricity"]], [5e-5])
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        if wrong_calls:
            for method, args in (
                ("setReal", ([vr["reset_counter"]], [1.0])),
                ("getInteger", ([vr["x"]],)),
                ("getString", ([vr["x"]],)),
                ("setBoolean", ([vr["damping"]], [True])),
                ("getReal", ([10**6],)),
            ):
                with pytest.raises(FMICallException) as refused:
                    getattr(fmu, method)(*args)
                assert refused.value.status == fmi2Error
        t, h = 0.0, 0.0025
        for _ in range(10):
            fmu.doStep(t, h)
            t += h
        runs.append(fmu.getReal([vr["x"], vr["vx"]]))
        assert fmu.getInteger([vr["reset_counter"]]) == [0]
        fmu.terminate()
        fmu.freeInstance()
    assert runs[0] == runs[1]  # bit for bit
    err = capfd.readouterr()
    log = err.out + err.err
    assert "variable reset_counter (value reference" in log
    assert "is of type Integer, not Real" in log
    assert "no variable has value reference 1000000" in log


def test_the_readme_lists_every_fmu():
    from pathlib import Path

    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    for ident in MODEL_IDENTIFIERS.values():
        assert f"`{ident}`" in readme, ident
