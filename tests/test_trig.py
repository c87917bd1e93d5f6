"""The forcing phase's cos and sin (components/trig.py) against libm's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rubcosim.components import trig
from rubcosim.components.jit import njit


@njit
def _all(x, c, s, c2, s2):
    for i in range(x.shape[0]):
        c[i] = trig.cos(x[i])
        s[i] = trig.sin(x[i])
        c2[i], s2[i] = trig.cos_sin(x[i])


def _ulps(ours: np.ndarray, libm: np.ndarray) -> np.ndarray:
    return np.abs(ours - libm) / np.spacing(np.abs(libm))


def _check(x: np.ndarray) -> tuple[float, float]:
    c, s, c2, s2 = (np.empty_like(x) for _ in range(4))
    _all(x, c, s, c2, s2)
    assert np.array_equal(c, c2) and np.array_equal(s, s2)  # one reduction, same values
    uc, us = _ulps(c, np.cos(x)), _ulps(s, np.sin(x))
    return float(uc.max()), float(us.max())


@pytest.mark.parametrize("width", [1.0, 10.0, 1e3, 1e6])
def test_within_one_ulp_of_libm_over_the_range(width):
    x = np.random.default_rng(3).uniform(-width, width, 200_000)
    assert max(_check(x)) <= 1.0


def test_next_to_the_zeros_every_digit_is_kept():
    # the doubles nearest k pi/2 (cos or sin there ~1e-16 k): a reduction that drops the
    # tail of pi/2 would be wrong by thousands of ulps here
    k = np.arange(1.0, 600_000.0)
    x = k * (np.pi / 2)
    for xs in (x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf), -x):
        assert max(_check(xs)) <= 1.0


def test_exact_values_and_the_ends_of_the_range():
    x = np.array([0.0, -0.0, np.pi / 2, -np.pi, 2e6, -3e7, np.inf, -np.inf, np.nan])
    c, s, c2, s2 = (np.empty_like(x) for _ in range(4))
    _all(x, c, s, c2, s2)
    assert c[0] == 1.0 and s[0] == 0.0 and math.copysign(1.0, s[1]) == -1.0
    big = slice(4, 6)  # beyond LIMIT: libm's own
    assert np.array_equal(c[big], np.cos(x[big])) and np.array_equal(s[big], np.sin(x[big]))
    assert np.all(np.isnan(c[6:])) and np.all(np.isnan(s[6:]))
