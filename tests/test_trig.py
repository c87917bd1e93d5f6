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


# The same formulas as plain numba code: trig writes them as LLVM instructions, which
# must change nothing.
_INV, _R = 0.6366197723675814, 6755399441055744.0
_HI, _MID, _LO = 1.5707963267948966, 6.123233995736766e-17, -1.4973849048591698e-33


@njit
def _formulas(x):
    k = (x * _INV + _R) - _R
    r = trig.fma(-k, _HI, x)
    p = -k * _MID
    pe = trig.fma(-k, _MID, -p)
    s = r + p
    b = s - r
    tail = trig.fma(-k, _LO, ((r - (s - b)) + (p - b)) + pe)
    head = s + tail
    y = (s - head) + tail
    z = head * head
    w = z * z
    rs = trig._S2 + z * (trig._S3 + z * trig._S4) + z * w * (trig._S5 + z * trig._S6)
    v = z * head
    ks = head - ((z * (0.5 * y - v * rs) - y) - v * trig._S1)
    rc = z * (trig._C1 + z * (trig._C2 + z * trig._C3))
    rc += w * w * (trig._C4 + z * (trig._C5 + z * trig._C6))
    u = 1.0 - 0.5 * z
    kc = u + (((1.0 - u) - 0.5 * z) + (z * rc - head * y))
    return ks, kc, int(k) & 3


@njit
def _both(x, out):
    for i in range(x.shape[0]):
        r, y, q = trig._reduce(x[i])
        out[i, 0], out[i, 1], out[i, 2] = trig._kernel_sin(r, y), trig._kernel_cos(r, y), q
        out[i, 3], out[i, 4], out[i, 5] = _formulas(x[i])


def test_the_instructions_are_the_formulas_bit_for_bit():
    x = np.random.default_rng(9).uniform(-1e6, 1e6, 300_000)
    x = np.concatenate([x, np.arange(1.0, 2000.0) * (np.pi / 2), [0.0, 1e-300, 0.7853]])
    out = np.empty((x.size, 6))
    _both(x, out)
    assert np.array_equal(out[:, :3], out[:, 3:])
