"""The one event locator (components.root_finding) against closed-form roots and scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rubcosim.components.root_finding import (
    F_CUR,
    MAX_TRIALS,
    R_B,
    R_D,
    R_F,
    R_X,
    X_CUR,
    advance,
    advance_with_rates,
    bracket,
    bracket_with_rates,
    crossed_end,
    hermite_first_root,
)


def run(f, ta: float, tb: float, xtol: float) -> tuple[float, int]:
    s = bracket(ta, f(ta), tb, f(tb), xtol)
    trials = 0
    while trials < MAX_TRIALS and not advance(s):
        s[F_CUR] = f(s[X_CUR])
        trials += 1
    return crossed_end(s), trials


@pytest.mark.parametrize("level", [0.1, 0.5, 0.9])
def test_locates_a_closed_form_root_on_the_crossed_side(level: float) -> None:
    # cos t - level falls through zero at acos(level) on [0, pi/2]
    def f(t: float) -> float:
        return math.cos(t) - level

    t, trials = run(f, 0.0, 0.5 * math.pi, 1e-13)
    root = math.acos(level)
    assert f(t) <= 0.0  # the event has happened at the returned time
    assert abs(t - root) <= 1e-13
    # three-point interpolation: far fewer trials than bisection's log2(width / xtol) = 44
    assert trials <= 12


def test_agrees_with_scipy_brentq() -> None:
    def f(t: float) -> float:
        return 1.0 - t**3 - 0.3 * math.sin(7.0 * t)

    t, _ = run(f, 0.0, 2.0, 1e-14)
    assert abs(t - brentq(f, 0.0, 2.0, xtol=1e-14)) <= 2e-14


def test_equal_values_fall_back_to_bisection() -> None:
    # a staircase: flat stretches give equal values at different points, where the
    # interpolation's denominators vanish; the locator must bisect, not fail
    def f(t: float) -> float:
        return 1.0 if t < 0.3 else -1.0

    t, trials = run(f, 0.0, 1.0, 1e-12)
    assert 0.3 <= t <= 0.3 + 1e-12
    assert trials <= 45


def test_a_zero_at_the_bracket_end_needs_no_trial() -> None:
    s = bracket(0.0, 1.0, 2.0, 0.0, 1e-12)
    assert advance(s)
    assert crossed_end(s) == 2.0
    assert np.isfinite(s).all()


def run_with_rates(f, df, ta: float, tb: float, xtol: float) -> tuple[float, int]:
    s = bracket_with_rates(ta, f(ta), df(ta), tb, f(tb), df(tb), xtol)
    trials = 0
    while trials < MAX_TRIALS and not advance_with_rates(s):
        s[R_F], s[R_D] = f(s[R_X]), df(s[R_X])
        trials += 1
    return s[R_B], trials


@pytest.mark.parametrize("gap", [4e-14, 1e-10, 1e-6])
def test_with_rates_a_grazing_root_near_one_end_takes_a_few_trials(gap: float) -> None:
    # a gap of `gap` m closing from rest at 50 m/s2 with a slight cubic term, over a step
    # of 2e-4 s: the root sqrt(2 gap / a) sits near the start of the bracket, where
    # values alone (Brent) crawl
    def f(t: float) -> float:
        return gap - 25.0 * t * t - 2e3 * t**3

    def df(t: float) -> float:
        return -50.0 * t - 6e3 * t * t

    root = brentq(f, 0.0, 2e-4, xtol=1e-22, rtol=1e-15)
    t, trials = run_with_rates(f, df, 0.0, 2e-4, 1e-12)
    assert f(t) <= 0.0 and 0.0 <= t - root <= 1e-12
    assert trials <= 5
    _, brent_trials = run(f, 0.0, 2e-4, 1e-12)
    assert brent_trials >= 2 * trials


def test_with_rates_finds_the_first_of_three_roots() -> None:
    # (t - 0.2)(t - 0.5)(t - 0.7), falling first at 0.2: the first crossing is the event
    def f(t: float) -> float:
        return -(t - 0.2) * (t - 0.5) * (t - 0.7)

    def df(t: float) -> float:
        return -((t - 0.5) * (t - 0.7) + (t - 0.2) * (t - 0.7) + (t - 0.2) * (t - 0.5))

    t, _ = run_with_rates(f, df, 0.0, 1.0, 1e-13)
    assert f(t) <= 0.0 and abs(t - 0.2) <= 1e-13
    # the interpolant's first root: exact for this cubic
    assert abs(hermite_first_root(f(0.0), df(0.0), f(1.0), df(1.0), 1.0) - 0.2) < 1e-15


@pytest.mark.parametrize("level", [0.1, 0.5, 0.9])
def test_with_rates_locates_a_closed_form_root_on_the_crossed_side(level: float) -> None:
    t, trials = run_with_rates(lambda t: math.cos(t) - level, lambda t: -math.sin(t),
                               0.0, 0.5 * math.pi, 1e-13)  # fmt: skip
    assert math.cos(t) - level <= 0.0 and 0.0 <= t - math.acos(level) <= 1e-13
    assert trials <= 6


def test_the_dop853_tableau_is_scipys():
    # the copy that spares importing scipy.integrate at start-up, element for element
    from scipy.integrate._ivp import dop853_coefficients as scipy_tableau

    from rubcosim.components import dop853_tableau as ours

    assert ours.N_STAGES == scipy_tableau.N_STAGES
    assert ours.N_STAGES_EXTENDED == scipy_tableau.N_STAGES_EXTENDED
    for name in ("A", "B", "C", "E3", "E5", "D"):
        assert np.array_equal(getattr(ours, name), getattr(scipy_tableau, name)), name
