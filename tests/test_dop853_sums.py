"""DOP853's sums written out (components/dop853_sums.py): the writer's output, and
bit for bit the loops over scipy's tableau that they replace."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rubcosim.components import dop853, dop853_sums, dop853_write
from rubcosim.components import dop853_tableau as tab
from rubcosim.components.jit import njit

N_EXT = tab.N_STAGES_EXTENDED
A = np.asarray(tab.A).reshape(N_EXT, N_EXT)


def _loop(coefs: np.ndarray, K: np.ndarray, i: int) -> float:
    """The replaced loop: ``acc = 0; acc += c[j] * K[j, i]`` over every j, in order."""
    acc = 0.0
    for j in range(coefs.shape[0]):
        acc += float(coefs[j]) * float(K[j, i])
    return acc


@pytest.fixture(scope="module")
def stages() -> np.ndarray:
    rng = np.random.default_rng(7)
    # signs and magnitudes spread over many binades, so that rounding order matters
    return rng.standard_normal((N_EXT, 3)) * 10.0 ** rng.uniform(-8, 8, (N_EXT, 3))


def test_the_written_sums_are_the_writers_output():
    assert Path(dop853_sums.__file__).read_text(encoding="utf-8") == dop853_write.source()


@njit
def _stage(K, s, y, h, out):
    dop853.stage_point(K, s, y, h, out)


@njit
def _sums(K, i):
    sums = dop853_sums
    return sums.solution_sum(K, i), sums.error_sums(K, i), sums.dense_sums(K, i)


def test_stage_points_equal_the_loop_bit_for_bit(stages):
    y = np.array([0.3, -1.7, 2.0e3])
    h = 0.0123
    out = np.empty(3)
    for s in range(N_EXT):
        _stage(stages, s, y, h, out)
        for i in range(3):
            want = float(y[i]) + _loop(A[s, :s], stages, i) * h
            assert out[i] == want, (s, i)


def test_solution_error_and_dense_sums_equal_the_loop_bit_for_bit(stages):
    for i in range(3):
        sol, (e5, e3), dense = _sums(stages, i)
        assert sol == _loop(np.asarray(tab.B), stages, i)
        assert e5 == _loop(np.asarray(tab.E5), stages, i)
        assert e3 == _loop(np.asarray(tab.E3), stages, i)
        for r in range(4):
            assert dense[r] == _loop(np.asarray(tab.D)[r], stages, i)
