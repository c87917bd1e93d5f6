"""The controller's compiled kernels on a buffer (components/flat_controller.py) against the
same history kept by numpy array operations (tests/controller_arrays.py, a second method):
the same history and the same outputs, bit for bit, through jumps of the fed-back signal
with their left limits, for every kind of delay and filter; the controller unit, which
runs the kernels on its history, keeps it too; and a rollback by restoring the buffer's
bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcosim.components.flat_controller import (
    FULL,
    OK,
    controller_outputs,
    controller_params,
    controller_step,
    make_room,
)
from rubcosim.components.units import make_unit

from controller_arrays import ArrayController

TAU = 2.1e-3
CASES = {
    "pyragas": {},
    "etdas": {"memory": 0.6},
    "etdas, velocity": {"memory": 0.4, "feedback": "velocity"},
    "etdas, sine delay": {"memory": 0.5, "modulation_amplitude": 3e-4,
                          "modulation_frequency": 900.0},
    "etdas, sawtooth delay": {"memory": 0.5, "modulation_amplitude": 3e-4,
                              "modulation_frequency": 1500.0, "modulation_shape": "sawtooth"},
    "etdas, telegraph delay": {"memory": 0.5, "modulation_amplitude": 3e-4,
                               "modulation_frequency": 1500.0, "modulation_shape": "telegraph",
                               "modulation_seed": 7},
    "switched on late": {"memory": 0.3, "t_on": 4e-3},
}  # fmt: skip


def motion(t: float, jumps: int) -> dict[str, float]:
    """A disc orbit whose velocity reverses (times 0.8) at each of ``jumps`` impacts so far."""
    sign = (-0.8) ** jumps
    return {
        "x": 1e-5 * math.sin(900.0 * t) + 2e-6 * jumps,
        "y": 1e-5 * math.cos(700.0 * t),
        "vx": sign * 9e-3 * math.cos(900.0 * t),
        "vy": -sign * 7e-3 * math.sin(700.0 * t),
    }


class Kernel:
    """The kernels with their buffer, driven like a unit."""

    def __init__(self, params: dict, rows: int = 4096) -> None:
        self.p = controller_params(params)
        self.cs = np.array([0.0, 0.0, math.nan])
        self.buf = np.zeros((rows, 6))
        self.scratch = np.zeros((rows + 1, 6))
        self.u = dict.fromkeys(("x", "y", "vx", "vy"), 0.0)

    def step(self, t: float) -> int:
        u = self.u
        return controller_step(self.p, self.cs, self.buf, self.scratch,
                               u["x"], u["y"], u["vx"], u["vy"], t)  # fmt: skip

    def outputs(self, t: float) -> np.ndarray:
        out = np.empty(3)
        u = self.u
        controller_outputs(self.p, self.cs, self.buf, self.scratch,
                           u["x"], u["y"], u["vx"], u["vy"], t, out)  # fmt: skip
        return out

    def history(self) -> np.ndarray:
        a, b = int(self.cs[0]), int(self.cs[1])
        return self.buf[a:b]


def drive(case: dict, steps: int = 400, h: float = 3.7e-5, units: list | None = None):
    """The array method and the kernels side by side; yields both after every step (and
    steps the ``units`` given alongside)."""
    params = {"gain": 1e5, "delay": TAU, "speed": 0.0, **case}
    unit = ArrayController(name="controller", **params)
    kernel = Kernel(unit.params)
    others = units if units is not None else []
    jumps, t = 0, 0.0
    for k in range(steps):
        if k % 37 == 36:  # an impact at t: the left limit first, then the jump
            for u in (unit, *others):
                u.do_step(t, 0.0)
            assert kernel.step(t) == OK
            jumps += 1
        u = motion(t, jumps)
        for v in (unit, *others):
            v.set_inputs(u)
        kernel.u = u
        for v in (unit, *others):
            v.do_step(t, h)
        assert kernel.step(t) == OK
        t += h
        yield unit, kernel, t


@pytest.mark.parametrize("name", sorted(CASES))
def test_kernels_keep_the_units_history_and_give_its_outputs_bit_for_bit(name):
    for unit, kernel, t in drive(CASES[name]):
        np.testing.assert_array_equal(kernel.history(), unit.state["history"])
        assert kernel.cs[2] == unit.state["start"]
        want = unit.get_outputs()
        got = kernel.outputs(t)
        assert (got[0], got[1], got[2]) == (want["ux"], want["uy"], want["current_delay"])


@pytest.mark.parametrize("name", ["etdas, telegraph delay", "switched on late"])
def test_the_controller_unit_keeps_the_same_history_and_outputs(name):
    # the unit runs the kernels on its own history (room for one step after it): its
    # rows and outputs are those of the kernels on one long buffer
    params = {"gain": 1e5, "delay": TAU, "speed": 0.0, **CASES[name]}
    unit = make_unit("controller", "delayed_feedback", **params)
    for _, kernel, t in drive(CASES[name], units=[unit]):
        np.testing.assert_array_equal(kernel.history(), unit.state["history"])
        want = kernel.outputs(t)
        got = unit.get_outputs()
        assert (got["ux"], got["uy"], got["current_delay"]) == (want[0], want[1], want[2])


def test_restoring_the_bounds_rolls_a_step_back_exactly():
    case = CASES["etdas, sawtooth delay"]
    runs = list(drive(case, steps=150))
    _, kernel, t = runs[-1]
    saved = kernel.cs.copy()
    before = kernel.history().copy()
    kernel.u = motion(t, 9)
    assert kernel.step(t) == OK  # a step taken, then rolled back
    kernel.cs[:] = saved
    np.testing.assert_array_equal(kernel.history(), before)


def test_making_room_moves_the_history_to_the_front_and_keeps_it():
    *_, (_, kernel, t) = drive(CASES["etdas, sine delay"], steps=300)
    rows = kernel.history().copy()
    outputs = kernel.outputs(t)
    assert kernel.cs[0] > 0.0  # the front was dropped
    free = kernel.buf.shape[0] - int(kernel.cs[1])
    assert make_room(kernel.cs, kernel.buf, free)  # room enough: nothing moves
    assert kernel.cs[0] > 0.0
    assert not make_room(kernel.cs, kernel.buf, kernel.buf.shape[0])  # moved, still short
    assert kernel.cs[0] == 0.0
    np.testing.assert_array_equal(kernel.history(), rows)
    np.testing.assert_array_equal(kernel.outputs(t), outputs)


def test_a_buffer_too_small_is_reported_and_leaves_the_history():
    params = {"gain": 1e5, "delay": TAU, "speed": 0.0, "memory": 0.5}
    unit = make_unit("controller", "delayed_feedback", **params)
    kernel = Kernel(unit.params, rows=8)
    t, status = 0.0, OK
    while status == OK:
        kernel.u = motion(t, 0)
        saved = kernel.cs.copy()
        status = kernel.step(t)
        t += 1e-5  # a delay of 210 steps: the history outgrows 8 rows
    assert status == FULL
    np.testing.assert_array_equal(kernel.cs, saved)
