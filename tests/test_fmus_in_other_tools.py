"""Our FMUs driven by other FMI hosts: a plain C program, and the Ecos co-simulation library."""

from __future__ import annotations

import ctypes
import math
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest

from rubcosim.fmus.build import MODEL_IDENTIFIERS
from rubcosim.orchestrator.fmu_unit import FmuUnit

from fmi_c_host import compile_host, run_host
from test_units import KEY_OF, step_size, stimulus

STEPS = 20


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


def _description(fmu: Path) -> tuple[str, dict[str, ET.Element]]:
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    return root.get("guid", ""), {v.get("name"): v for v in root.iter("ScalarVariable")}


@pytest.mark.parametrize("ident", sorted(MODEL_IDENTIFIERS.values()))
def test_c_host_runs_each_fmu_like_fmpy_does(built_fmus, host, tmp_path, ident):
    """A C program with no Python of its own (clean environment, no LD_PRELOAD, no
    PYTHONPATH) steps the FMU and exits cleanly, with the same numbers as in-process fmpy."""
    fmu = built_fmus[ident]
    params, inputs = stimulus(KEY_OF[ident])
    h = step_size(KEY_OF[ident][0])
    guid, variables = _description(fmu)
    reals = {n: v for n, v in variables.items() if v.find("Real") is not None}
    sets = {n: float(v) for n, v in {**params, **inputs(0.0)}.items() if n in reals}
    outputs = [n for n, v in reals.items() if v.get("causality") == "output"]
    proc = run_host(
        host,
        fmu,
        tmp_path,
        guid,
        gets=[int(reals[n].get("valueReference")) for n in outputs],
        sets={int(reals[n].get("valueReference")): value for n, value in sets.items()},
        steps=STEPS,
        step=h,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for marker in ("Fatal", "Segmentation", "Traceback", "core dumped", "corrupted"):
        assert marker not in proc.stderr
    rows = np.array([[float(x) for x in line.split(",")] for line in proc.stdout.split()])
    assert rows.shape == (STEPS, 1 + len(outputs))
    want = []
    with FmuUnit(fmu, params={n: v for n, v in sets.items() if n in params}) as unit:
        unit.set_inputs({n: v for n, v in sets.items() if n not in params})
        for i in range(STEPS):
            unit.do_step(i * h, h)
            o = unit.get_outputs()
            want.append([(i + 1) * h, *[o[n] for n in outputs]])
    np.testing.assert_array_equal(rows[:, 1:], np.array(want)[:, 1:])


def _ecospy():
    tbb = Path(sys.prefix) / "lib" / "libtbb.so.12"
    if tbb.exists():  # the tbb wheel puts it here, off the loader's search path
        ctypes.CDLL(str(tbb), mode=ctypes.RTLD_GLOBAL)
    return pytest.importorskip("ecospy")


def test_ecos_runs_a_rotor_against_an_elastic_stator(built_fmus, tmp_path):
    """Two of our FMUs coupled in Ecos (fixed step, its own master) rub as the reference does."""
    ecospy = _ecospy()
    from rubcosim.reference import build_system, make_unit, simulate

    rotor = dict(mass=10.0, damping=316.227766, stiffness=1e6, eccentricity=5e-5,
                 speed=379.473319, disc_radius=0.05)  # fmt: skip
    stator = dict(clearance=1e-4, contact_stiffness=2e7, friction=0.02, restitution=0.9)
    h, n = 2e-6, 15000  # 0.03 s: about two forcing periods, several contacts
    with ecospy.EcosSimulationStructure() as ss:
        ss.add_model("rotor", str(built_fmus["RubcosimJeffcottRotor"]))
        ss.add_model("stator", str(built_fmus["RubcosimElasticStator"]))
        for v in ("x", "y", "vx", "vy"):
            ss.make_real_connection(f"rotor::{v}", f"stator::{v}")
        for f in ("fx", "fy"):
            ss.make_real_connection(f"stator::{f}", f"rotor::{f}")
        start = {f"rotor::{k}": v for k, v in rotor.items()}
        start.update({f"stator::{k}": v for k, v in stator.items()})
        start.update({"stator::speed": rotor["speed"], "stator::disc_radius": 0.05,
                      "stator::impact_mass": rotor["mass"]})  # fmt: skip
        ss.add_parameter_set("init", start)
        with ecospy.EcosSimulation(structure=ss, step_size=h) as sim:
            sim.init(0.0, "init")
            xs = []
            for _ in range(n // 100):
                sim.step(100)
                xs.append((sim.get_real("rotor::x"), sim.get_real("rotor::y")))
            sim.terminate()
    units = {
        "rotor": make_unit("rotor", "jeffcott", rotor),
        "stator": make_unit("stator", "elastic", stator),
    }
    times = h * 100 * np.arange(1, n // 100 + 1)
    ref = simulate(build_system(units), float(times[-1]), t_eval=np.concatenate(([0.0], times)))
    want = np.stack([ref.output("rotor.x")[1:], ref.output("rotor.y")[1:]], axis=1)
    err = np.max(np.hypot(*(np.array(xs) - want).T))
    assert np.max(np.hypot(*want.T)) > 1e-4  # it does reach the stator
    # a fixed-step Jacobi master without event handling: first order, a few % of the clearance
    assert err < 0.05 * 1e-4, err
    assert math.isfinite(err)


def test_rigid_impact_protocol_drives_two_fmus_like_the_reference(built_fmus):
    """The documented stator -> rotor reset protocol, driven by a minimal event-locating
    master over fmpy: the impact times and rebounds match the monolithic reference."""
    from rubcosim.reference import build_system, make_unit, simulate

    rotor = dict(mass=10.0, damping=316.227766, stiffness=1e6, eccentricity=5e-5,
                 speed=379.473319, disc_radius=0.05)  # fmt: skip
    stator = dict(clearance=1e-4, restitution=0.8, friction=0.15)
    units = {
        "rotor": make_unit("rotor", "jeffcott", rotor),
        "stator": make_unit("stator", "rigid", stator),
    }
    ref = simulate(build_system(units), 0.03, output_step=1e-3)
    ref_impacts = ref.events.t[ref.events.of_kind("impact")][:3]
    assert ref_impacts.size == 3

    h, t, impacts, rebounds = 1e-4, 0.0, [], []
    extra = {"speed": rotor["speed"], "disc_radius": rotor["disc_radius"]}
    with (
        FmuUnit(built_fmus["RubcosimJeffcottRotor"], params=rotor) as rfmu,
        FmuUnit(built_fmus["RubcosimRigidStator"], params={**stator, **extra}) as sfmu,
    ):

        def gap_after(t0: float, dt: float, saved) -> float:
            rfmu.set_state(saved)
            rfmu.do_step(t0, dt)
            o = rfmu.get_outputs()
            sfmu.set_inputs({k: o[k] for k in ("x", "y", "vx", "vy")})
            return sfmu.get_outputs()["gap"]

        while len(impacts) < 3:
            saved = rfmu.get_state()
            if gap_after(t, h, saved) >= 0.0:
                t += h
            else:  # bisect the step onto the crossing, then apply the impact
                lo, hi = 0.0, h
                while hi - lo > 1e-13:
                    mid = 0.5 * (lo + hi)
                    lo, hi = (lo, mid) if gap_after(t, mid, saved) < 0.0 else (mid, hi)
                gap_after(t, lo, saved)
                t += lo
                o = sfmu.get_outputs()
                rfmu.set_inputs({"reset_vx": o["vx_plus"], "reset_vy": o["vy_plus"],
                                 "reset_counter": len(impacts) + 1})  # fmt: skip
                rfmu.do_step(t, 0.0)
                assert rfmu.get_outputs()["resets_applied"] == len(impacts) + 1
                impacts.append(t)
                rebounds.append((o["vx_plus"], o["vy_plus"]))
            rfmu.free_state(saved)
    np.testing.assert_allclose(impacts, ref_impacts, rtol=0, atol=1e-9)
    ref_states = ref.events.state[ref.events.of_kind("impact")][:3, 2:4]
    np.testing.assert_allclose(rebounds, ref_states, rtol=1e-6)
