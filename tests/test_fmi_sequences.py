"""Random FMI 2.0 co-simulation call sequences against rubcosim's own FMUs (issue 49, item 3).

Hypothesis draws call sequences that follow the FMI 2.0 co-simulation state machine (FMI
2.0.5, section 4.2.4): fmi2SetupExperiment and fixed parameters while instantiated; inputs,
parameters and outputs in Initialization Mode; then inputs, input derivatives (through
fmi2SetRealInputDerivatives or the tunable carriers), every variable read back, fmi2DoStep
from the FMU's time, FMU states got, set, freed, serialised and deserialised; fmi2Terminate;
fmi2Reset back to instantiated.  Each FMU runs in this process through fmpy's low-level
FMU2Slave, from one extraction per FMU.

The reference is the unit class the FMU wraps, imported from the FMU's own bundle: the same
source running as plain Python, as inside the FMU.  It is stepped with the same inputs, and
sent back to a deep copy of itself, taken when the FMU's state was, where the FMU restores
that state.  Every value read must be the reference's bit for bit.  A step the unit refuses
(non-finite inputs, a state that is not finite) must be refused by the FMU too, with
fmi2Discard or fmi2Error, and the FMU must stay where it was.

Invalid calls are mixed in: wrongly typed gets and sets, value references no variable has,
fmi2DoStep from another time or with a step that is not a positive finite number.  Each must
be refused (fmi2Error; fmi2Discard or fmi2Error for fmi2DoStep), never answered fmi2OK or
fmi2Fatal, and must change nothing: the sequence goes on and must still match.

Invalid calls that pythonfmu once answered with fmi2Fatal (dropping references it did not
own, so that the process crashed at the next such call) are drawn as well: an output set,
a fixed parameter set in step mode, a NaN input derivative, bytes that are not a state;
outputs read in a state the unit has none for must be refused with fmi2Error.  Each of
those answers, and the other FMI 2.0 requirements the fuzz cannot draw (stopTime, a state
got in Initialization Mode, input derivatives set before initialisation, ...), is also
checked once per FMU in a subprocess by test_an_invalid_call_gets_the_answer_fmi_2_requires
(REQUIRED), where a crash is an answer too.  Should a drawn call answer fmi2Fatal, the test
fails and the instance's Python slave is kept alive (_pin), so that the run goes on.

RUBCOSIM_FUZZ_EXAMPLES=n draws n sequences per FMU instead of the default.
"""

from __future__ import annotations

import copy
import gc
import json
import math
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Discard, fmi2Error, fmi2Fatal, fmi2OK
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fmus import KEY_OF, step_of, stimulus_params

from rubcosim.components.units import UNIT_CLASSES

# --- what is fuzzed ---------------------------------------------------------------------

EXAMPLES = int(os.environ.get("RUBCOSIM_FUZZ_EXAMPLES", "60"))
MAX_CALLS = 40  # calls per sequence, after the instantiation

# Fixed-parameter sets a sequence may write while instantiated or initialising (every fixed
# parameter at once: the example values, overridden by these): each is a valid unit.
PARAMETER_SETS = {
    "RubcosimImpactOscillator": (
        {},
        stimulus_params("RubcosimImpactOscillator"),
        {
            **stimulus_params("RubcosimImpactOscillator"),
            "stop": "rigid_two_sided",
            "cubic_stiffness": 1.0,
            "x0": 0.2,
            "v0": -0.5,
        },
    ),
    "RubcosimJeffcottRotor": (
        {},
        {"eccentricity": 5e-5, "damping": 316.2},
        {"eccentricity": 5e-5, "damping": 316.2, "integrator": "dop853", "x0": 1e-6, "vy0": 1e-3},
    ),
    "RubcosimRigidStator": (
        {},
        stimulus_params("RubcosimRigidStator"),
        {
            **stimulus_params("RubcosimRigidStator"),
            "restitution": 0.5,
            "x_offset": 1e-5,
            "disc_mass": 10.0,
        },
    ),
    "RubcosimDelayedFeedbackController": (
        {},
        stimulus_params("RubcosimDelayedFeedbackController"),
        {
            **stimulus_params("RubcosimDelayedFeedbackController"),
            "feedback": "velocity",
            "modulation_shape": "sawtooth",
            "delay_periods": 2,
            "modulation_seed": 7,
            "t_on": 2e-4,
        },
    ),
    "RubcosimElasticStator": (
        {},
        stimulus_params("RubcosimElasticStator"),
        {**stimulus_params("RubcosimElasticStator"), "x_offset": 1e-5, "contact_damping": 50.0},
    ),
    "RubcosimHuntCrossleyStator": (
        {},
        stimulus_params("RubcosimHuntCrossleyStator"),
        {**stimulus_params("RubcosimHuntCrossleyStator"), "x_offset": 1e-5, "exponent": 1.0},
    ),
    "RubcosimCasingStator": (
        {},
        stimulus_params("RubcosimCasingStator"),
        {**stimulus_params("RubcosimCasingStator"), "damping": 100.0, "x0": 1e-6, "vy0": 1e-3},
    ),
    "RubcosimTwoMassRotor": (
        {},
        {"eccentricity": 5e-5, "damping": 100.0, "shaft_damping": 20.0},
        {"eccentricity": 5e-5, "damping": 100.0, "integrator": "dop853", "journal_x0": 1e-6},
    ),
    "RubcosimLinearBearing": ({}, {"stiffness": 2e7, "damping": 500.0}),
    "RubcosimAnisotropicBearing": ({}, {"kxy": 1.5e6, "kyx": -1.5e6, "cxx": 400.0}),
    "RubcosimOilFilmBearing": ({}, {"viscosity": 0.03, "speed": 400.0}),
    "RubcosimTwoDofImpactOscillator": (
        {},
        stimulus_params("RubcosimTwoDofImpactOscillator"),
        {**stimulus_params("RubcosimTwoDofImpactOscillator"), "x1_0": 0.04, "v2_0": -0.2},
    ),
}
FUZZED = sorted(PARAMETER_SETS)
# The casing stator's reference integrates with scipy at rtol 1e-10 in plain Python: a drawn
# sequence with contact took minutes.  Its answers to the REQUIRED cases are still checked.
SEQUENCES = [ident for ident in FUZZED if ident != "RubcosimCasingStator"]

# The size of each input's values (a real input is drawn from [-size, size]; an integer
# input from the range given): the sizes of the stimuli of tests/test_units.py, so that
# the disc reaches the stator's clearance (1e-4 m) and the oscillator its barrier.
INPUT_SIZES = {
    "RubcosimImpactOscillator": {"force": 2.0},
    "RubcosimJeffcottRotor": {
        "fx": 100.0,
        "fy": 100.0,
        "reset_vx": 0.05,
        "reset_vy": 0.05,
        "reset_counter": (-1, 3),
    },
    "RubcosimRigidStator": {
        "x": 1.2e-4,
        "y": 1.2e-4,
        "vx": 0.05,
        "vy": 0.05,
        "other_fx": 100.0,
        "other_fy": 100.0,
        "contact_mode": (-1, 4),
    },
    "RubcosimDelayedFeedbackController": {"x": 2e-5, "y": 2e-5, "vx": 0.02, "vy": 0.02},
    "RubcosimElasticStator": {"x": 1.2e-4, "y": 1.2e-4, "vx": 0.05, "vy": 0.05},
    "RubcosimCasingStator": {"x": 1.2e-4, "y": 1.2e-4, "vx": 0.05, "vy": 0.05},
    "RubcosimHuntCrossleyStator": {"x": 1.2e-4, "y": 1.2e-4, "vx": 0.05, "vy": 0.05},
    "RubcosimTwoMassRotor": {
        "fx": 100.0,
        "fy": 100.0,
        "reset_vx": 0.05,
        "reset_vy": 0.05,
        "reset_counter": (-1, 3),
        "journal_fx": 100.0,
        "journal_fy": 100.0,
    },
    "RubcosimLinearBearing": {"x": 5e-5, "y": 5e-5, "vx": 0.01, "vy": 0.01},
    "RubcosimAnisotropicBearing": {"x": 5e-5, "y": 5e-5, "vx": 0.01, "vy": 0.01},
    # the film's clearance is 1.5e-4 m: a journal drawn outside it has no outputs
    "RubcosimOilFilmBearing": {"x": 1.2e-4, "y": 1.2e-4, "vx": 0.01, "vy": 0.01},
    "RubcosimTwoDofImpactOscillator": {"force": 2.0},
}

STEP_FACTORS = (1.0, 1.0, 0.5, 2.0, 0.3)  # communication step = factor * step_of(FMU)
NON_FINITE = (math.nan, math.inf, -math.inf)
FMI_TYPES = ("Real", "Integer", "Boolean", "String")
BAD_STEPS = ("negative", "nan", "inf", "time_nan", "time_behind", "time_ahead")


def _fmi_type(kind: str) -> str:
    return {"real": "Real", "int": "Integer", "integer": "Integer", "choice": "String"}[kind]


@dataclass(frozen=True)
class Declared:
    """An FMU's variables as its unit class declares them (known before any FMU is built,
    so that the strategies can be made at import)."""

    ident: str
    params: dict[str, str]  # fixed parameter -> FMI type
    inputs: dict[str, str]  # input -> FMI type
    outputs: dict[str, str]
    carriers: tuple[tuple[str, int], ...]  # (real input, derivative order)
    count: int  # number of variables: value references 0 .. count - 1

    @classmethod
    def of(cls, ident: str) -> Declared:
        unit = UNIT_CLASSES[KEY_OF[ident]]
        inputs = {s.name: _fmi_type(s.kind) for s in unit.inputs}
        carriers = tuple((n, k) for n, t in inputs.items() if t == "Real" for k in (1, 2))
        return cls(
            ident,
            {p.name: _fmi_type(p.kind) for p in unit.params_spec},
            inputs,
            {s.name: _fmi_type(s.kind) for s in unit.outputs},
            carriers,
            len(unit.params_spec) + len(inputs) + len(carriers) + len(unit.outputs),
        )

    def variables(self) -> dict[str, str]:
        carriers = {f"{n}_d{k}": "Real" for n, k in self.carriers}
        return {**self.params, **carriers, **self.inputs, **self.outputs}


DECLARED = {ident: Declared.of(ident) for ident in FUZZED}


# --- the sequences -------------------------------------------------------------------------
# A sequence is a list of calls, each a tuple of plain values (so that a failing one can be
# kept in KEPT below as it is printed):
#   ("setup", start, stop)        fmi2SetupExperiment (stop None: no stop time defined)
#   ("parameters", k)             every fixed parameter to PARAMETER_SETS[ident][k]
#   ("enter",) ("exit",)          fmi2Enter/ExitInitializationMode
#   ("input", name, value)        fmi2SetReal / fmi2SetInteger on an input
#   ("derivative", name, order, value, via)   via "fmi2SetRealInputDerivatives" or
#                                 "carrier" (fmi2SetReal on the tunable <name>_d<order>)
#   ("step", factor)              fmi2DoStep(time, factor * step_of(ident))
#   ("get",)                      every variable the state allows, compared with the unit
#   ("get_state",) ("set_state", i) ("free_state", i) ("serialize", i) ("deserialize", j)
#                                 i counts the FMU states got or deserialised, j the byte
#                                 strings serialised, in order
#   ("terminate",) ("reset",)
#   ("wrong_type", function, name)     e.g. ("wrong_type", "getInteger", "x")
#   ("unknown_reference", function, vr)
#   ("bad_step", kind)            kind in BAD_STEPS


def _value(draw, size) -> float | int:
    if isinstance(size, tuple):
        return draw(st.integers(*size))
    pick = draw(st.integers(0, 24))
    if pick == 0:
        return draw(st.sampled_from(NON_FINITE))
    if pick == 1:
        return 0.0
    return draw(st.floats(-1.0, 1.0)) * size


@st.composite
def call_sequences(draw, ident: str) -> list[tuple]:
    """A call sequence the FMI 2.0 co-simulation state machine allows, invalid calls mixed in."""
    d = DECLARED[ident]
    sizes = INPUT_SIZES[ident]
    real_inputs = [n for n, t in d.inputs.items() if t == "Real"]
    variables = d.variables()
    phase, set_up, set_since_step = "instantiated", False, False
    states: list[bool] = []  # FMU states: live or freed
    blobs = 0
    calls: list[tuple] = []

    def wrong_type():
        name = draw(st.sampled_from(sorted(variables)))
        kind = draw(st.sampled_from([t for t in FMI_TYPES if t != variables[name]]))
        return ("wrong_type", draw(st.sampled_from(["get", "set"])) + kind, name)

    def unknown_reference():
        function = draw(st.sampled_from([g + t for g in ("get", "set") for t in FMI_TYPES]))
        vr = draw(st.sampled_from([d.count, d.count + 1, 65535, 65536, 2**31, 2**32 - 1]))
        return ("unknown_reference", function, vr)

    def set_output():
        return ("set_output", draw(st.sampled_from(sorted(d.outputs))))

    def fixed_parameter():  # refused in step mode only
        k = draw(st.integers(0, len(PARAMETER_SETS[ident]) - 1))
        return ("fixed_parameter", k)

    def nan_derivative():
        via = draw(st.sampled_from(["fmi2SetRealInputDerivatives", "carrier"]))
        return ("nan_derivative", draw(st.sampled_from(real_inputs)), via)

    def garbage_state():
        return ("garbage_state", draw(st.sampled_from([b"", b"garbage", b"{}", b'{"time": 0}'])))

    for _ in range(draw(st.integers(1, MAX_CALLS))):
        live = [i for i, alive in enumerate(states) if alive]
        # the weights: most calls in step mode, there mostly inputs, steps and reads
        if phase == "instantiated":
            menu = ["enter"] * 4 if set_up else ["setup"] * 4
            menu += ["parameters", "parameters", "invalid"]
        elif phase == "initialization":
            menu = ["input"] * 3 + ["exit"] * 4 + ["parameters", "get", "invalid"]
        elif phase == "step":
            menu = ["input"] * 5 + ["step"] * 8 + ["derivative"] * 2 + ["get_state"] * 2
            menu += ["bad_step", "invalid", "terminate", "reset"]
            menu += [] if set_since_step else ["get"] * 3
            menu += ["set_state"] * 3 + ["free_state"] + ["serialize"] * 2 if live else []
            menu += ["deserialize"] * 2 if blobs else []
        else:  # terminated
            menu = ["get", "reset"]
        kind = draw(st.sampled_from(menu))
        if kind == "setup":
            call = (
                "setup",
                draw(st.sampled_from([0.0, 0.0, 0.25])),
                draw(st.sampled_from([None, 1e6])),
            )
            set_up = True
        elif kind == "parameters":
            call = ("parameters", draw(st.integers(0, len(PARAMETER_SETS[ident]) - 1)))
        elif kind == "enter":
            call, phase = ("enter",), "initialization"
        elif kind == "exit":
            call, phase = ("exit",), "step"
        elif kind == "input":
            name = draw(st.sampled_from(sorted(d.inputs)))
            call, set_since_step = ("input", name, _value(draw, sizes[name])), True
        elif kind == "derivative":
            name = draw(st.sampled_from(real_inputs))
            order = draw(st.sampled_from([1, 2]))
            value = draw(st.floats(-1.0, 1.0)) * sizes[name] / step_of(ident) ** order
            via = draw(st.sampled_from(["fmi2SetRealInputDerivatives", "carrier"]))
            call, set_since_step = ("derivative", name, order, value, via), True
        elif kind == "step":
            call, set_since_step = ("step", draw(st.sampled_from(STEP_FACTORS))), False
        elif kind == "get":
            call = ("get",)
        elif kind == "get_state":
            call = ("get_state",)
            states.append(True)
        elif kind in ("set_state", "free_state", "serialize"):
            i = draw(st.sampled_from(live))
            call = (kind, i)
            if kind == "free_state":
                states[i] = False
            blobs += kind == "serialize"
        elif kind == "deserialize":
            call = ("deserialize", draw(st.integers(0, blobs - 1)))
            states.append(True)
        elif kind == "terminate":
            call, phase = ("terminate",), "terminated"
        elif kind == "reset":
            call, phase, set_up, set_since_step = ("reset",), "instantiated", False, False
        elif kind == "invalid":
            menu = [wrong_type, unknown_reference, set_output, nan_derivative, garbage_state]
            menu += [fixed_parameter] if phase == "step" else []
            call = draw(st.sampled_from(menu))()
            set_since_step |= call[0] != "wrong_type" or call[1].startswith("set")
        else:
            call = ("bad_step", draw(st.sampled_from(BAD_STEPS)))
        calls.append(call)
    return calls


# --- the FMUs and their reference ------------------------------------------------------------


def bundled_unit_class(unzipped: Path, ident: str) -> type:
    """The unit class inside an FMU, as the FMU runs it: the ``unit_class`` of the slave
    class pythonfmu imported from the FMU's bundle when an instance was made."""
    module = (unzipped / "resources" / "slavemodule.txt").read_text().strip()
    return getattr(sys.modules[module], ident).unit_class


@dataclass
class Rig:
    """One FMU, extracted once: its variables, its unit class and its step."""

    ident: str
    unzipped: Path
    guid: str
    vr: dict[str, int]
    fmi_type: dict[str, str]
    unit_class: type | None
    step: float
    parameter_sets: list[dict]
    instances: int = field(default=0)

    def instantiate(self) -> FMU2Slave:
        self.instances += 1
        fmu = FMU2Slave(
            guid=self.guid,
            unzipDirectory=str(self.unzipped),
            modelIdentifier=self.ident,
            instanceName=f"{self.ident}-{self.instances}",
        )
        fmu.instantiate()
        return fmu


@pytest.fixture(scope="module")
def rigs(built_fmus, tmp_path_factory):
    out = {}
    for ident in FUZZED:
        path = built_fmus[ident]
        md = read_model_description(str(path))
        unzipped = Path(extract(str(path), unzipdir=str(tmp_path_factory.mktemp(ident))))
        variables = {v.name: v for v in md.modelVariables}
        assert {n: v.type for n, v in variables.items()} == DECLARED[ident].variables()
        vr = {n: v.valueReference for n, v in variables.items()}
        types = {n: v.type for n, v in variables.items()}
        rig = Rig(ident, unzipped, md.guid, vr, types, None, step_of(ident), [])
        rig.instantiate().freeInstance()  # pythonfmu imports the FMU's bundle
        rig.unit_class = unit_class = bundled_unit_class(unzipped, ident)
        sets = [{**unit_class.example_params(), **s} for s in PARAMETER_SETS[ident]]
        for s in sets:
            unit_class(**s)  # valid, or this raises naming the parameter
        rig.parameter_sets = sets
        out[ident] = rig
    return out


def _answer(function, *args):
    """(status, result) of one fmpy call: fmi2OK, or the status fmpy raised for."""
    try:
        return fmi2OK, function(*args)
    except FMICallException as exc:
        return exc.status, None


_PINNED: list = []


def _pin(ident: str, instance_name: str) -> None:
    """After an fmi2Fatal, keep the instance's Python slave alive: pythonfmu dropped a
    reference to it it still uses, and the garbage collector would free it under the
    instance (a segfault, later, anywhere in the test run).  The instance is not called
    again, not even freed."""
    for o in gc.get_objects():
        if type(o).__name__ == ident and vars(o).get("instance_name") == instance_name:
            _PINNED.append(o)


STATUS = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal"}


def _bits(value) -> object:
    """A value as compared: floats by their bits (-0.0 is not 0.0, nan is nan)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, float):
        return value.hex()
    return value


@dataclass
class Snapshot:
    """What an FMU state holds, for the reference: the unit, its time, the parameters."""

    unit: object
    time: float
    params: dict


class Session:
    """One FMU instance driven by a call sequence, next to its reference."""

    def __init__(self, rig: Rig):
        self.rig = rig
        self.fmu = rig.instantiate()
        self.freed = self.dead = False
        self._fresh()
        self.handles: list = []  # FMU states, None once freed
        self.snapshots: list[Snapshot] = []
        self.blobs: list[tuple[bytes, Snapshot]] = []
        self.log: list[tuple] = []

    def _fresh(self) -> None:
        self.phase = "instantiated"
        self.params = dict(self.rig.unit_class.example_params())
        self.start = 0.0
        self.initial_inputs: dict = {}
        self.unit = None
        self.time = math.nan

    # --- checks -----------------------------------------------------------------------------
    def fail(self, message: str) -> None:
        calls = "\n".join(f"  {i:2d} {c!r}" for i, c in enumerate(self.log))
        pytest.fail(f"{self.rig.ident}, call {len(self.log) - 1} {self.log[-1]!r}: {message}\n"
                    f"sequence so far:\n{calls}")  # fmt: skip

    def answer(self, function, *args):
        status, result = _answer(function, *args)
        if status == fmi2Fatal:
            _pin(self.rig.ident, self.fmu.instanceName)
            self.dead = True
            self.fail("answered fmi2Fatal")
        return status, result

    def ok(self, function, *args):
        status, result = self.answer(function, *args)
        if status != fmi2OK:
            self.fail(f"a valid call answered {STATUS[status]}")
        return result

    def refused(self, allowed, function, *args) -> None:
        status, _ = self.answer(function, *args)
        if status not in allowed:
            want = " or ".join(STATUS[s] for s in allowed)
            self.fail(f"an invalid call answered {STATUS[status]}, not {want}")

    # --- the calls --------------------------------------------------------------------------
    def run(self, calls: list[tuple]) -> None:
        try:
            for call in calls:
                self.log.append(call)
                getattr(self, f"_{call[0]}")(*call[1:])
            self.log.append(("end",))
            self._end()
        finally:
            if not (self.freed or self.dead):
                self.fmu.freeInstance()

    def _end(self) -> None:
        if self.phase == "step":
            self.ok(self.fmu.terminate)
        for handle in self.handles:
            if handle is not None:
                self.ok(self.fmu.freeFMUstate, handle)
        self.fmu.freeInstance()
        self.freed = True

    def _setup(self, start, stop) -> None:
        self.ok(self.fmu.setupExperiment, None, start, stop)
        self.start = start

    def _parameters(self, k) -> None:
        values = self.rig.parameter_sets[k]
        for kind, setter in (("Real", self.fmu.setReal), ("Integer", self.fmu.setInteger),
                             ("String", self.fmu.setString)):  # fmt: skip
            names = [n for n in values if self.rig.fmi_type[n] == kind]
            self.ok(setter, [self.rig.vr[n] for n in names], [values[n] for n in names])
        self.params = dict(values)

    def _enter(self) -> None:
        self.ok(self.fmu.enterInitializationMode)
        self.phase = "initialization"

    def _initial_unit(self):
        unit = self.rig.unit_class(**self.params)
        unit.reset(self.start)
        unit.set_inputs(self.initial_inputs)
        return unit

    def _exit(self) -> None:
        self.ok(self.fmu.exitInitializationMode)
        self.unit, self.time, self.phase = self._initial_unit(), self.start, "step"

    def _input(self, name, value) -> None:
        setter = self.fmu.setInteger if self.rig.fmi_type[name] == "Integer" else self.fmu.setReal
        if isinstance(value, float) and not math.isfinite(value):
            # FMI 2.0 lets fmi2SetReal refuse it (fmi2Discard or fmi2Error); accepted, the
            # next step must fail, as the unit's does
            status, _ = self.answer(setter, [self.rig.vr[name]], [value])
            if status not in (fmi2OK, fmi2Discard, fmi2Error):
                self.fail(f"a non-finite input answered {STATUS[status]}")
            if status != fmi2OK:
                return
        else:
            self.ok(setter, [self.rig.vr[name]], [value])
        if self.phase == "initialization":
            self.initial_inputs[name] = value
        else:
            self.unit.set_input(name, value)

    def _derivative(self, name, order, value, via) -> None:
        if via == "carrier":
            self.ok(self.fmu.setReal, [self.rig.vr[f"{name}_d{order}"]], [value])
        else:
            self.ok(self.fmu.setRealInputDerivatives, [self.rig.vr[name]], [order], [value])
        self.unit.set_input_derivative(name, order, value)

    def _step(self, factor) -> None:
        h = self.rig.step * factor
        before = copy.deepcopy(self.unit)
        try:
            self.unit.do_step(self.time, h)
        except self.unit_step_error():
            self.refused((fmi2Discard, fmi2Error), self.fmu.doStep, self.time, h)
            return
        if self._outputs(self.unit) is not None:
            self.ok(self.fmu.doStep, self.time, h)
        else:  # a state with no outputs: refusing the step is as good as taking it
            status, _ = self.answer(self.fmu.doStep, self.time, h)
            if status in (fmi2Discard, fmi2Error):
                self.unit = before
                return
            if status != fmi2OK:
                self.fail(f"a step to a state with no outputs answered {STATUS[status]}")
        self.time = self.time + h

    def unit_step_error(self) -> type:
        base = next(c for c in self.rig.unit_class.__mro__ if c.__name__ == "Unit")
        return sys.modules[base.__module__].StepError

    def _bad_step(self, kind) -> None:
        h, t = self.rig.step, self.time
        t, h = {"negative": (t, -h), "nan": (t, math.nan), "inf": (t, math.inf),
                "time_nan": (math.nan, h), "time_behind": (t - h, h),
                "time_ahead": (t + 2 * h, h)}[kind]  # fmt: skip
        self.refused((fmi2Discard, fmi2Error), self.fmu.doStep, t, h)

    def _outputs(self, unit) -> dict | None:
        """The unit's outputs, or None where it has none (OutputError, e.g. the rigid stator
        told to slide with no disc mass): there the FMU must refuse to read them with
        fmi2Error (``_get``)."""
        try:
            return dict(unit.get_outputs())
        except ValueError:
            return None

    def _expected(self) -> dict:
        """Every variable readable in the current phase, as the reference has it."""
        if self.phase == "initialization":  # outputs only (FMI 2.0, 4.2.4, condition 2)
            return self._outputs(self._initial_unit()) or {}
        values = self._outputs(self.unit) or {}
        values.update(self.params)
        values.update(self.unit.u)
        for name, order in DECLARED[self.rig.ident].carriers:
            values[f"{name}_d{order}"] = self.unit.du.get(name, (0.0, 0.0))[order - 1]
        return values

    def _get(self) -> None:
        unit = self._initial_unit() if self.phase == "initialization" else self.unit
        if self._outputs(unit) is None:  # every output read is refused
            getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger}
            for name in DECLARED[self.rig.ident].outputs:
                kind = self.rig.fmi_type[name]
                self.refused((fmi2Error,), getter[kind], [self.rig.vr[name]])
        want = self._expected()
        got = {}
        for kind, getter in (("Real", self.fmu.getReal), ("Integer", self.fmu.getInteger),
                             ("String", self.fmu.getString)):  # fmt: skip
            names = [n for n in want if self.rig.fmi_type[n] == kind]
            if names:
                got.update(
                    zip(names, self.ok(getter, [self.rig.vr[n] for n in names]), strict=True)
                )
        cast = {"Real": float, "Integer": int, "String": str}
        differ = {
            n: (got[n], w)
            for n, w in want.items()
            if _bits(got[n]) != _bits(cast[self.rig.fmi_type[n]](w))
        }
        if differ:
            self.fail(f"read (FMU, unit): {differ}")

    def _snapshot(self) -> Snapshot:
        return Snapshot(copy.deepcopy(self.unit), self.time, dict(self.params))

    def _restore(self, snap: Snapshot) -> None:
        self.unit, self.time, self.params = copy.deepcopy(snap.unit), snap.time, dict(snap.params)

    def _get_state(self) -> None:
        self.handles.append(self.ok(self.fmu.getFMUstate))
        self.snapshots.append(self._snapshot())

    def _set_state(self, i) -> None:
        self.ok(self.fmu.setFMUstate, self.handles[i])
        self._restore(self.snapshots[i])

    def _free_state(self, i) -> None:
        self.ok(self.fmu.freeFMUstate, self.handles[i])
        self.handles[i] = None

    def _serialize(self, i) -> None:
        self.blobs.append((bytes(self.ok(self.fmu.serializeFMUstate, self.handles[i])),
                           self.snapshots[i]))  # fmt: skip

    def _deserialize(self, j) -> None:
        blob, snap = self.blobs[j]
        self.handles.append(self.ok(self.fmu.deSerializeFMUstate, blob))
        self.snapshots.append(snap)

    def _terminate(self) -> None:
        self.ok(self.fmu.terminate)
        self.phase = "terminated"

    def _reset(self) -> None:
        self.ok(self.fmu.reset)
        self._fresh()

    def _wrong_type(self, function, name) -> None:
        vr = self.rig.vr[name]
        args = ([vr],) if function.startswith("get") else ([vr], [_ANY[function[3:]]])
        self.refused((fmi2Error,), getattr(self.fmu, function), *args)

    def _unknown_reference(self, function, vr) -> None:
        args = ([vr],) if function.startswith("get") else ([vr], [_ANY[function[3:]]])
        self.refused((fmi2Error,), getattr(self.fmu, function), *args)

    def _set_output(self, name) -> None:
        kind = self.rig.fmi_type[name]
        setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger}[kind]
        self.refused((fmi2Error,), setter, [self.rig.vr[name]], [_ANY[kind]])

    def _fixed_parameter(self, k) -> None:
        """Any fixed parameter set in step mode, even to the value it has: fmi2Error."""
        values = self.rig.parameter_sets[k]
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "String": self.fmu.setString}  # fmt: skip
        name = sorted(values)[k % len(values)]
        self.refused(
            (fmi2Error,), setters[self.rig.fmi_type[name]], [self.rig.vr[name]], [values[name]]
        )

    def _nan_derivative(self, name, via) -> None:
        if via == "carrier":
            self.refused((fmi2Error,), self.fmu.setReal, [self.rig.vr[f"{name}_d1"]], [math.nan])
        else:
            args = ([self.rig.vr[name]], [1], [math.nan])
            self.refused((fmi2Error,), self.fmu.setRealInputDerivatives, *args)

    def _garbage_state(self, blob) -> None:
        self.refused((fmi2Error,), self.fmu.deSerializeFMUstate, blob)


_ANY = {"Real": 1.0, "Integer": 1, "Boolean": True, "String": "x"}

# The suite's run draws the same sequences every time (derandomize): a sequence can take
# seconds (the casing stator's reference integrates with scipy at rtol 1e-10 in plain
# Python), and a random draw made one CI run minutes longer.  RUBCOSIM_FUZZ_EXAMPLES (make
# fuzz) draws new ones at every run.
FUZZ_SETTINGS = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize="RUBCOSIM_FUZZ_EXAMPLES" not in os.environ,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


# a non-finite input makes the unit's outputs nan (the FMU's as well): numpy warns
NAN_INPUTS = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")


@NAN_INPUTS
@pytest.mark.parametrize("ident", SEQUENCES)
@FUZZ_SETTINGS
@given(data=st.data())
def test_random_valid_call_sequences_match_the_unit_and_invalid_calls_change_nothing(
    rigs, ident, data
):
    Session(rigs[ident]).run(data.draw(call_sequences(ident), label="calls"))


# Sequences kept: the fuzz's failures (none so far besides those the strict xfails below
# hold) and sequences through the paths most easily broken: a state serialised, the FMU
# reset and initialised with other parameters, the state deserialised and restored; steps
# refused for a non-finite input or wrong arguments, then stepping on; derivatives through
# either route; a state restored twice and freed.
KEPT = [
    ("RubcosimJeffcottRotor", [
        ("setup", 0.0, None), ("parameters", 2), ("enter",), ("input", "fx", 30.0), ("exit",),
        ("step", 1.0), ("get_state",), ("serialize", 0), ("step", 2.0), ("get",), ("reset",),
        ("setup", 0.25, 1e6), ("parameters", 1), ("enter",), ("exit",), ("step", 1.0),
        ("deserialize", 0), ("set_state", 1), ("get",), ("step", 0.5), ("get",),
        ("set_state", 0), ("step", 0.5), ("get",), ("free_state", 0), ("terminate",), ("get",),
    ]),
    ("RubcosimRigidStator", [
        ("setup", 0.0, None), ("parameters", 1), ("enter",), ("exit",), ("input", "x", 1.1e-4),
        ("input", "vx", 0.04), ("step", 1.0), ("get",), ("input", "y", math.nan),
        ("step", 1.0), ("get",), ("bad_step", "time_behind"), ("input", "y", 1e-5),
        ("input", "contact_mode", 3), ("step", 1.0), ("get",), ("bad_step", "nan"),
        ("wrong_type", "getInteger", "gap"), ("unknown_reference", "setReal", 65536),
        ("step", 2.0), ("get",),
    ]),
    ("RubcosimDelayedFeedbackController", [
        ("setup", 0.0, None), ("parameters", 1), ("enter",), ("input", "x", 1e-5), ("get",),
        ("exit",), ("step", 1.0), ("get_state",), ("derivative", "x", 1, 0.1, "carrier"),
        ("derivative", "y", 2, -300.0, "fmi2SetRealInputDerivatives"), ("step", 1.0), ("get",),
        ("step", 2.0), ("set_state", 0), ("step", 1.0), ("get",), ("set_state", 0),
        ("step", 1.0), ("get",), ("free_state", 0),
    ]),
    # found by the fuzz: a sliding contact with no disc mass has no outputs
    ("RubcosimRigidStator", [
        ("setup", 0.0, None), ("enter",), ("input", "contact_mode", 1), ("exit",),
        ("step", 1.0), ("get",), ("terminate",), ("get",),
    ]),
    # found by the fuzz: the controller's state before its first step, through bytes
    ("RubcosimDelayedFeedbackController", [
        ("setup", 0.0, None), ("enter",), ("exit",), ("get_state",), ("serialize", 0),
        ("step", 1.0), ("deserialize", 0), ("set_state", 1), ("get",), ("step", 1.0), ("get",),
    ]),
    ("RubcosimImpactOscillator", [
        ("setup", 0.0, None), ("parameters", 2), ("enter",), ("exit",), ("input", "force", 1.5),
        ("step", 2.0), ("get_state",), ("step", 2.0), ("get",), ("bad_step", "negative"),
        ("bad_step", "inf"), ("bad_step", "time_ahead"), ("set_state", 0), ("get",),
        ("step", 1.0), ("get",), ("wrong_type", "setString", "x0"), ("terminate",), ("get",),
    ]),
]  # fmt: skip


@NAN_INPUTS
@pytest.mark.parametrize(
    ("ident", "calls"), KEPT, ids=[f"{k}-{i}" for i, (k, _) in enumerate(KEPT)]
)
def test_kept_call_sequences_match_the_unit(rigs, ident, calls):
    Session(rigs[ident]).run(calls)


# --- the invalid calls the FMUs answer wrongly today --------------------------------------------
# Each case runs in a subprocess on fresh instances (an fmi2Fatal from pythonfmu leaves the
# process one garbage collection away from a segfault), for every FMU in FUZZED and the
# oil-film bearing, and prints one JSON line per FMU: whether the answer is the one FMI 2.0
# requires, and what came.  The spec it is given says, per FMU, what a case needs (None:
# the case is not run on that FMU).

KNOWN_SCRIPT = r"""
import gc, json, math, os, sys
gc.disable()  # a dangling reference left by an fmi2Fatal must not be collected mid-run
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

NAMES = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal"}
specs = json.loads(sys.argv[1])


def answer(function, *args):
    try:
        return 0, function(*args)
    except FMICallException as exc:
        return exc.status, None


class Fmu:
    def __init__(self, ident, spec):
        self.ident, self.spec, self.n = ident, spec, 0
        md = read_model_description(spec["path"])
        self.md, self.unzipped = md, extract(spec["path"], unzipdir=os.path.abspath(ident))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.var = {v.name: v for v in md.modelVariables}
        self.h = spec["step"]

    def new(self, start=True, stop=None, step=True):
        self.n += 1
        f = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipped,
                      modelIdentifier=self.ident, instanceName=f"known{self.n}")
        f.instantiate()
        if start:
            f.setupExperiment(startTime=0.0, stopTime=stop)
            f.enterInitializationMode()
            f.exitInitializationMode()
            if step:
                f.doStep(0.0, self.h)
        return f

    def outputs(self, f):
        names = [n for n, v in self.var.items() if v.causality == "output" and v.type == "Real"]
        return f.getReal([self.vr[n] for n in names])


def refused_with_error(status):
    return status == 3


def case_set_an_output(u):
    out = next(n for n, v in u.var.items() if v.causality == "output")
    setter = {"Real": "setReal", "Integer": "setInteger"}[u.var[out].type]
    status, _ = answer(getattr(u.new(), setter), [u.vr[out]], [1])
    return refused_with_error(status), f"{setter}({out}) in step mode: {NAMES[status]}"


def _nan_derivative(u, via):
    f = u.new()
    name = u.spec["real_input"]
    if via == "carrier":
        status, _ = answer(f.setReal, [u.vr[name + "_d1"]], [math.nan])
    else:
        status, _ = answer(f.setRealInputDerivatives, [u.vr[name]], [1], [math.nan])
    then = None
    if status == 0:  # accepted: the next step must be refused, as for a non-finite input
        then, _ = answer(f.doStep, u.h, u.h)
    good = status in (2, 3) or (status == 0 and then in (2, 3))
    text = f"{via} {name} order 1 = nan: {NAMES[status]}"
    return good, text + (f", then fmi2DoStep: {NAMES[then]}" if then is not None else "")


def case_nan_input_derivative(u):
    return _nan_derivative(u, "fmi2SetRealInputDerivatives")


def case_nan_derivative_carrier(u):
    return _nan_derivative(u, "carrier")


def case_several_values_with_one_refused_change_nothing(u):
    f = u.new()
    name = u.spec["real_input"]
    refs = [u.vr[name], u.vr[name + "_d1"]]
    before = f.getReal(refs)
    status, _ = answer(f.setReal, refs, [before[0] + 1.0, math.nan])
    after = f.getReal(refs)
    text = (f"fmi2SetReal({name} = {before[0] + 1.0}, {name}_d1 = nan): {NAMES[status]}; "
            f"({name}, {name}_d1) {before} before, {after} after")
    return refused_with_error(status) and after == before, text


def case_deserialize_bytes_that_are_no_state(u):
    blob = bytes(u.new().serializeFMUstate(u.new().getFMUstate()))
    got = []
    for garbage in (b"", b"garbage", blob[:-5]):
        status, _ = answer(u.new().deSerializeFMUstate, garbage)
        got.append((garbage[:12], NAMES[status]))
    return all(s == "fmi2Error" for _, s in got), f"fmi2DeSerializeFMUstate: {got}"


def case_set_a_state_that_is_no_state(u):
    f = u.new()
    status, state = answer(f.deSerializeFMUstate, b"{}")
    if status != 0:
        return refused_with_error(status), f"fmi2DeSerializeFMUstate(b'{{}}'): {NAMES[status]}"
    status, _ = answer(f.setFMUstate, state)
    text = f"fmi2DeSerializeFMUstate(b'{{}}'): fmi2OK, then fmi2SetFMUstate: {NAMES[status]}"
    return refused_with_error(status), text


def _fixed_parameter_in_step_mode(u, same):
    if u.spec["parameter"] is None:
        return None
    name, value = u.spec["parameter"]
    if same:
        value = u.var[name].start
        value = float(value) if u.var[name].type == "Real" else value
    f, twin = u.new(), u.new()
    setter = {"Real": f.setReal, "Integer": f.setInteger, "String": f.setString}[u.var[name].type]
    status, _ = answer(setter, [u.vr[name]], [value])
    then, _ = answer(f.doStep, u.h, u.h)
    twin.doStep(u.h, u.h)
    same_outputs = then == 0 and u.outputs(f) == u.outputs(twin)
    text = (f"set {name} = {value!r} after a step: {NAMES[status]}; then fmi2DoStep from the "
            f"FMU's time: {NAMES[then]}, outputs {'as' if same_outputs else 'NOT as'} an "
            "instance that never saw the call")
    return refused_with_error(status) and same_outputs, text


def case_fixed_parameter_set_in_step_mode_to_another_value(u):
    return _fixed_parameter_in_step_mode(u, same=False)


def case_fixed_parameter_set_in_step_mode_to_its_own_value(u):
    return _fixed_parameter_in_step_mode(u, same=True)


def case_step_past_the_stop_time(u):
    f = u.new(stop=u.h)  # initialised with stopTime = h and stepped to h
    status, _ = answer(f.doStep, u.h, u.h)
    return refused_with_error(status), f"stopTime {u.h}, fmi2DoStep({u.h}, {u.h}): {NAMES[status]}"


def case_a_step_of_zero_size_changes_nothing(u):
    got = []
    for h in (0.0, -0.0):
        f = u.new()  # at t = step
        before = u.outputs(f)
        status, _ = answer(f.doStep, u.h, h)
        same = status == 0 and u.outputs(f) == before
        then, _ = answer(f.doStep, u.h, u.h)  # the FMU is still at t = step
        got.append((h, NAMES[status], "outputs as before" if same else "outputs CHANGED",
                    NAMES[then]))  # fmt: skip
    good = all(s == "fmi2OK" and same == "outputs as before" and t == "fmi2OK"
               for _, s, same, t in got)  # fmt: skip
    return good, f"fmi2DoStep(step, h), then fmi2DoStep(step, step): {got}"


def case_invalid_step_arguments_are_fmi2error_not_fmi2discard(u):
    got = []
    t, h = u.h, u.h
    for label, args in (("h < 0", (t, -h)), ("h nan", (t, math.nan)), ("h inf", (t, math.inf)),
                        ("t nan", (math.nan, h)), ("t behind", (0.0, h)),
                        ("t ahead", (t + 2 * h, h))):
        status, _ = answer(u.new().doStep, *args)
        got.append((label, NAMES[status]))
    return all(s == "fmi2Error" for _, s in got), f"fmi2DoStep: {got}"


def case_last_successful_time_after_a_step_from_a_wrong_time(u):
    f = u.new()  # at t = h
    status, _ = answer(f.doStep, 5 * u.h, u.h)
    last = f.getRealStatus(2) if status == 2 else None  # fmi2LastSuccessfulTime
    good = status == 3 or last == u.h
    return good, (f"fmi2DoStep({5 * u.h}, {u.h}) at t = {u.h}: {NAMES[status]}; "
                  f"fmi2LastSuccessfulTime = {last}")


def case_input_derivative_set_before_initialisation(u):
    name = u.spec["real_input"]
    d1 = u.spec["derivative"]
    carried, outputs = {}, {}
    for where in ("instantiated", "initialization", "step"):
        f = u.new(start=False)
        if where == "instantiated":
            f.setRealInputDerivatives([u.vr[name]], [1], [d1])
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        if where == "initialization":
            f.setRealInputDerivatives([u.vr[name]], [1], [d1])
        f.exitInitializationMode()
        if where == "step":
            f.setRealInputDerivatives([u.vr[name]], [1], [d1])
        carried[where] = f.getReal([u.vr[name + "_d1"]])[0]
        f.doStep(0.0, u.h)
        outputs[where] = u.outputs(f)
    good = len({str(v) for v in outputs.values()}) == 1 and set(carried.values()) == {d1}
    return good, (f"fmi2SetRealInputDerivatives({name}, 1, {d1}) (fmi2OK) while instantiated "
                  f"or initialising: {name}_d1 after fmi2ExitInitializationMode reads "
                  f"{carried}; first step's outputs "
                  + ("equal" if len({str(v) for v in outputs.values()}) == 1 else "differ"))


def case_state_taken_in_initialization_mode(u):
    if u.spec["initial_value"] is None:
        return None
    name, value, output = u.spec["initial_value"]
    f = u.new(start=False)
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.setReal([u.vr[name]], [value])
    state = f.getFMUstate()
    read = f.getReal([u.vr[output]])[0]  # at the time of the state
    f.setReal([u.vr[name]], [2 * value])
    f.setFMUstate(state)
    back = f.getReal([u.vr[output]])[0]
    return back == read, (f"Initialization Mode: {name} = {value}, fmi2GetFMUstate, "
                          f"{output} reads {read}; {name} = {2 * value}, fmi2SetFMUstate: "
                          f"{output} reads {back}")


def case_invalid_parameter_at_exit_initialization_mode(u):
    name, bad = u.spec["bad_parameter"]
    f = u.new(start=False)
    f.setReal([u.vr[name]], [bad])
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    status, _ = answer(f.exitInitializationMode)
    return refused_with_error(status), f"{name} = {bad}: fmi2ExitInitializationMode {NAMES[status]}"


def case_state_serialised_before_the_first_step(u):
    got = []
    for what in ("step", "read"):
        f = u.new(step=False)
        before = u.outputs(f)
        blob = bytes(f.serializeFMUstate(f.getFMUstate()))
        f.doStep(0.0, u.h)
        status, state = answer(f.deSerializeFMUstate, blob)
        if status == 0:
            status, _ = answer(f.setFMUstate, state)
        got.append(("restore", NAMES[status]))
        if what == "step":
            got.append(("fmi2DoStep", NAMES[answer(f.doStep, 0.0, u.h)[0]]))
        else:
            status, back = answer(u.outputs, f)
            got.append(("outputs", NAMES[status] if status else back == before))
    want = [("restore", "fmi2OK"), ("fmi2DoStep", "fmi2OK"), ("restore", "fmi2OK"),
            ("outputs", True)]
    good = got == want
    return good, ("fmi2GetFMUstate right after initialisation, serialised, deserialised and "
                  f"set after a step: {got}")


def case_outputs_the_unit_cannot_compute(u):
    if u.spec["no_outputs"] is None:
        return None
    name, value = u.spec["no_outputs"]
    f = u.new()
    setter = {"Real": f.setReal, "Integer": f.setInteger}[u.var[name].type]
    setter([u.vr[name]], [value])
    step, _ = answer(f.doStep, u.h, u.h)
    if step in (2, 3):  # refused: the state is still one with outputs
        return True, f"{name} = {value}: fmi2DoStep {NAMES[step]}"
    out = next(n for n, v in u.var.items() if v.causality == "output" and v.type == "Real")
    status, _ = answer(f.getReal, [u.vr[out]])
    return refused_with_error(status), (f"{name} = {value}: fmi2DoStep {NAMES[step]}, then "
                                        f"fmi2GetReal({out}) {NAMES[status]}")


CASES = [name for name in dict(globals()) if name.startswith("case_")]
fmus = {ident: Fmu(ident, spec) for ident, spec in specs.items()}
for case in CASES:
    for ident, u in fmus.items():
        try:
            result = globals()[case](u)
        except Exception as exc:  # fmpy raising where the case expected fmi2OK
            result = False, f"{type(exc).__name__}: {exc}"
        if result is None:  # the case needs something this FMU's spec does not give
            continue
        good, text = result
        row = {"case": case[5:], "ident": ident, "good": good, "text": text}
        print(json.dumps(row), flush=True)

# last, as it may end the process: two refused calls on one instance, then a collection
u = next(iter(fmus.values()))
f = u.new()
got = [NAMES[answer(f.deSerializeFMUstate, b"garbage")[0]] for _ in range(2)]
gc.collect()
f.doStep(u.h, u.h)
row = {"case": "two_refused_calls_on_one_instance", "ident": u.ident,
       "good": got == ["fmi2Error"] * 2,
       "text": f"fmi2DeSerializeFMUstate twice: {got}, process alive after gc.collect()"}
print(json.dumps(row), flush=True)
os._exit(0)  # no interpreter teardown over the references an fmi2Fatal left dangling
"""

# What FMI 2.0 requires of each case, and what the FMUs answered before it was met (commit
# ed37cc5; fmus/fmi_slave.py and the loader shim now refuse with fmi2Error and never let a
# Python exception reach pythonfmu).
REQUIRED = {
    "set_an_output": "fmi2SetReal/fmi2SetInteger on an output: fmi2Error (FMI 2.0, 2.1.2); "
    "was fmi2Fatal (the output has no setter)",
    "nan_input_derivative": "fmi2SetRealInputDerivatives with a NaN: refused, or the next step "
    "refused; was fmi2Fatal (a ValueError inside the carrier's setter)",
    "nan_derivative_carrier": "fmi2SetReal of NaN on a tunable <input>_d1 carrier: refused; "
    "was fmi2Fatal",
    "several_values_with_one_refused_change_nothing": "fmi2SetReal of a new input value and "
    "a NaN derivative in one call: fmi2Error, and the input keeps its value (a refused call "
    "changes nothing); the input was set",
    "deserialize_bytes_that_are_no_state": "fmi2DeSerializeFMUstate of bytes that are not a "
    "serialised state (empty, garbage, truncated): fmi2Error; was fmi2Fatal",
    "set_a_state_that_is_no_state": "fmi2DeSerializeFMUstate(b'{}'): fmi2Error; was fmi2OK, "
    "then fmi2Fatal at fmi2SetFMUstate",
    "fixed_parameter_set_in_step_mode_to_another_value": "a fixed parameter set after "
    "initialisation: fmi2Error and no change (FMI 2.0, 4.2.4 condition 6); was fmi2OK and a "
    "unit silently rebuilt at the start time",
    "fixed_parameter_set_in_step_mode_to_its_own_value": "a fixed parameter set after "
    "initialisation to the value it has: fmi2Error as well; was fmi2OK",
    "step_past_the_stop_time": "fmi2DoStep past the stopTime of fmi2SetupExperiment: "
    "fmi2Error (FMI 2.0, 2.1.6); stopTime was ignored",
    "a_step_of_zero_size_changes_nothing": "rubcosim's choice: fmi2DoStep with a step of 0 "
    "(or -0) is fmi2OK and changes nothing but what new inputs at that instant change "
    "(rubcosim's master takes such steps at events: orchestrator/event_steps.py)",
    "invalid_step_arguments_are_fmi2error_not_fmi2discard": "fmi2DoStep with h < 0, a "
    "non-finite h or t, or t not the FMU's time: fmi2Error, a step not carried out at all "
    "(FMI 2.0, 4.2.2); was fmi2Discard, which means 'computed only a subinterval'",
    "last_successful_time_after_a_step_from_a_wrong_time": "after fmi2DoStep from a wrong time, "
    "fmi2Error (or fmi2LastSuccessfulTime the end of the last step); was fmi2Discard with the "
    "wrong time as fmi2LastSuccessfulTime",
    "input_derivative_set_before_initialisation": "input derivatives set while instantiated or "
    "in Initialization Mode (allowed, FMI 2.0 4.2.4) are kept; were dropped at "
    "fmi2ExitInitializationMode",
    "state_taken_in_initialization_mode": "an FMU state got in Initialization Mode after a "
    "parameter changed restores that parameter's unit; restored the old one",
    "invalid_parameter_at_exit_initialization_mode": "an invalid parameter value: "
    "fmi2ExitInitializationMode answers fmi2Error; was fmi2Fatal",
    "state_serialised_before_the_first_step": "an FMU state got before the first step (the "
    "controller's empty (0, 6) delay history) survives serialisation; came back with shape "
    "(0,), then every step fmi2Discard and every output fmi2Fatal",
    "outputs_the_unit_cannot_compute": "outputs read in a state the unit has none for (the "
    "rigid stator with contact_mode = 1 and disc_mass = 0; the oil film with the journal "
    "outside it): fmi2Error; was fmi2Fatal",
    "two_refused_calls_on_one_instance": "two refused calls on one instance, then a garbage "
    "collection: the process lives; crashed with SIGSEGV (pythonfmu's exception path)",
}


# per FMU: a fixed parameter to change after initialisation; one that sets an output's
# initial value (parameter, value, output); an input value that leads to a state with no
# outputs (KNOWN_SCRIPT runs on every fuzzed FMU; a case an FMU has no entry for is skipped).
CHANGED_PARAMETER = {
    "RubcosimImpactOscillator": ("damping", 0.5),
    "RubcosimJeffcottRotor": ("damping", 100.0),
    "RubcosimRigidStator": ("friction", 0.3),
    "RubcosimDelayedFeedbackController": ("gain", 5e4),
    "RubcosimElasticStator": ("friction", 0.3),
    "RubcosimCasingStator": ("damping", 50.0),
    "RubcosimHuntCrossleyStator": ("friction", 0.3),
    "RubcosimTwoMassRotor": ("shaft_damping", 10.0),
    "RubcosimLinearBearing": ("damping", 300.0),
    "RubcosimAnisotropicBearing": ("cyy", 250.0),
    "RubcosimOilFilmBearing": ("viscosity", 0.05),
    "RubcosimTwoDofImpactOscillator": ("damping1", 0.05),
}
INITIAL_VALUE = {
    "RubcosimImpactOscillator": ("x0", 0.25, "x"),
    "RubcosimJeffcottRotor": ("x0", 1e-5, "x"),
    "RubcosimRigidStator": ("x_offset", 2e-5, "gap"),
    "RubcosimDelayedFeedbackController": ("delay", 3.7e-4, "current_delay"),
    "RubcosimCasingStator": ("x0", 1e-6, "casing_x"),
    "RubcosimTwoMassRotor": ("x0", 1e-5, "x"),
    "RubcosimTwoDofImpactOscillator": ("x1_0", 0.03, "x1"),
}
NO_OUTPUTS = {"RubcosimRigidStator": ("contact_mode", 1), "RubcosimOilFilmBearing": ("x", 1.0)}


def _known_spec(ident: str, path: Path) -> dict:
    unit = UNIT_CLASSES[KEY_OF[ident]]
    real_input = next(s.name for s in unit.inputs if s.kind == "real")
    bad = next(p for p in unit.params_spec if p.kind == "real" and math.isfinite(p.low))
    size = INPUT_SIZES.get(ident, {}).get(real_input, 1e-5)
    return {
        "path": str(path),
        "step": step_of(ident),
        "real_input": real_input,
        "derivative": size / step_of(ident),
        "parameter": CHANGED_PARAMETER.get(ident),
        "bad_parameter": (bad.name, bad.low - 1.0),
        "initial_value": INITIAL_VALUE.get(ident),
        "no_outputs": NO_OUTPUTS.get(ident),
    }


@pytest.fixture(scope="module")
def known_answers(built_fmus, tmp_path_factory):
    """Case -> [(FMU, whether the answer is the one FMI 2.0 requires, what came)]."""
    specs = {i: _known_spec(i, built_fmus[i]) for i in FUZZED}
    proc = subprocess.run(
        [sys.executable, "-c", KNOWN_SCRIPT, json.dumps(specs)],
        capture_output=True, text=True, timeout=300, check=False,
        cwd=tmp_path_factory.mktemp("known"),
    )  # fmt: skip
    answers: dict[str, list] = {case: [] for case in REQUIRED}
    for line in proc.stdout.splitlines():
        if line.startswith('{"case"'):
            row = json.loads(line)
            answers[row["case"]].append((row["ident"], row["good"], row["text"]))
    for rows in answers.values():
        if not rows:  # the process ended before the case: a crash is an answer too
            rows.append(("-", False, f"no answer: the process ended with {proc.returncode}, "
                         f"stderr {proc.stderr[-500:]!r}"))  # fmt: skip
    return answers


@pytest.mark.parametrize("case", sorted(REQUIRED))
def test_an_invalid_call_gets_the_answer_fmi_2_requires(known_answers, case):
    """Each case of REQUIRED, on every FMU it applies to, in one subprocess."""
    wrong = [f"{ident}: {text}" for ident, good, text in known_answers[case] if not good]
    assert not wrong, "\n".join(wrong)


def test_every_known_case_is_run():
    cases = {m for m in re.findall(r"^def case_(\w+)\(", KNOWN_SCRIPT, re.M)}
    assert cases | {"two_refused_calls_on_one_instance"} == set(REQUIRED)
