"""The engines' scratch arrays on the stack (rubcosim.reference.stack_arrays).

Wiring and layout tests: shapes, C-order strides, independent buffers, and a DOP853
step computed on stack arrays equal, bit for bit, to the same step on heap arrays.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import pytest
from numba.core.errors import TypingError

from rubcosim.components.dop853 import N_EXT, N_STAGES, C, solution_point, stage_point
from rubcosim.reference.layout import LAYOUT, MAX_STATES
from rubcosim.reference.stack_arrays import stack_floats, stack_ints, stack_matrix

CAP = 24
K_CAP = N_EXT * 4


@nb.njit
def _filled(rows, cols):
    a = stack_floats(CAP, rows * cols)
    b = stack_ints(CAP, rows * cols)
    m = stack_matrix(CAP, rows, cols)
    for i in range(rows * cols):
        a[i] = 0.5 * i
        b[i] = -i
    for r in range(rows):
        for c in range(cols):
            m[r, c] = 100.0 * r + c
    # every element of each array read back after all three were written: no overlap
    return a.copy(), b.copy(), m.copy(), m.strides[0], m.strides[1]


def test_stack_arrays_shapes_strides_and_independent_buffers() -> None:
    a, b, m, s0, s1 = _filled(3, 5)
    assert np.array_equal(a, 0.5 * np.arange(15))
    assert np.array_equal(b, -np.arange(15))
    assert np.array_equal(m, 100.0 * np.arange(3)[:, None] + np.arange(5)[None, :])
    assert (s0, s1) == (5 * 8, 8)


@nb.njit
def _one_step(on_stack, y0, h):
    n = y0.shape[0]
    if on_stack:
        K, y, y_new, ytmp = (stack_matrix(K_CAP, N_EXT, n), stack_floats(4, n),
                             stack_floats(4, n), stack_floats(4, n))  # fmt: skip
    else:
        K, y, y_new, ytmp = np.empty((N_EXT, n)), np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        y[i] = y0[i]
    # a Duffing oscillator x'' + 0.1 x' + x + x^3 = cos(1.2 t), one DOP853 step from t = 0
    K[0, 0] = y[1]
    K[0, 1] = 1.0 - 0.1 * y[1] - y[0] - y[0] ** 3
    for s in range(1, N_STAGES):
        stage_point(K, s, y, h, ytmp)
        K[s, 0] = ytmp[1]
        K[s, 1] = np.cos(1.2 * C[s] * h) - 0.1 * ytmp[1] - ytmp[0] - ytmp[0] ** 3
    solution_point(K, y, h, y_new)
    return y_new.copy()


def test_a_dop853_step_on_stack_arrays_equals_the_heap_one() -> None:
    y0 = np.array([0.3, -0.2])
    assert np.array_equal(_one_step(True, y0, 0.25), _one_step(False, y0, 0.25))


@nb.njit
def _capacity_from_an_expression(n):
    return stack_floats(CAP + 1, n)


def test_a_capacity_that_is_not_a_constant_is_refused_when_compiled() -> None:
    with pytest.raises(TypingError, match="compile-time constant"):
        _capacity_from_an_expression(3)


def test_max_states_covers_every_assembled_system() -> None:
    # every bundled scenario's system fits the engines' stack arrays, and so does every
    # rotor-family system (at most one state per slot of the layout) and hybrid type
    import rubcosim as rc
    from rubcosim.components.hybrid_dispatch import hybrid_types

    sizes = [rc.load(name).system.n_state for name in rc.scenarios()]
    assert max(sizes) <= MAX_STATES
    assert all(len(t.states) <= MAX_STATES for t in hybrid_types())
    assert len(LAYOUT.ip_state) <= MAX_STATES


def test_numba_is_the_release_pyproject_pins() -> None:
    """The names numba does not document that rubcosim relies on (this module's
    ``cgutils.alloca_once``/``make_array``, jit's ``_nrt`` option for ``borrows=True``)
    were written against one numba release; pyproject pins it.  Another numba in this
    environment (installed by hand) fails here first, by name, rather than somewhere
    in a kernel."""
    import tomllib
    from pathlib import Path

    from packaging.requirements import Requirement

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    deps = tomllib.loads(pyproject.read_text())["project"]["dependencies"]
    pin = next(Requirement(d) for d in deps if Requirement(d).name == "numba")
    assert pin.specifier.contains(nb.__version__), (
        f"numba {nb.__version__} is not the release pyproject pins ({pin.specifier})"
    )
    assert pin.specifier.contains("0.68.1") and not pin.specifier.contains("0.69.0")
