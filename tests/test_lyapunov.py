"""Variational equations on the fast engine: Lyapunov spectra and monodromy matrices.

Each check compares with an independent figure: a closed form (the damping, Newton's
restitution), a symmetry of the model (the rotating Jeffcott rotor), or a second
method (finite differences of the stroboscopic map)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rubcosim.analysis.errors import AnalysisError
from rubcosim.analysis.floquet import FLOQUET_RTOL, floquet
from rubcosim.analysis.lyapunov import lyapunov_spectrum, monodromy
from rubcosim.analysis.maps import StroboscopicMap, model_of
from rubcosim.cli import main
from rubcosim.reference.history import full_rhs_alloc
from rubcosim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
DUFFING = SCENARIOS / "impact_duffing.toml"  # b = 0.1, w = 2 (T = pi), R = 0.8
ROTOR = SCENARIOS / "jeffcott_elastic_stator.toml"
WN = 316.227766  # the rotor's natural frequency, rad/s (m = 10 kg, k = 1e6 N/m)
# a penalty stator without contact damping (restitution 1), friction 0.05: partial rub
# with about three contacts per revolution that never settles into synchronous whirl
ROTOR_RUB = [
    "stator.restitution=1.0",
    "stator.friction=0.05",
    "rotor.eccentricity=1e-4",
    f"rotor.speed={1.3 * WN!r}",
    "rotor.x0=1.5e-4",
]


def fd_jacobian(smap: StroboscopicMap, y: np.ndarray, n: int, mode: int) -> np.ndarray:
    """The second method: central differences of the n-fold map (1e-5 scales).

    Not 1e-6: the map is integrated to 1e-12, and where a step ends on the kink of an
    elastic stop its error is not smooth in y, so its noise over 1e-6 reached 1e-5 of
    the derivative on some points of the orbit (a change of the forcing's cos by an
    ulp moved the elastic case from 5e-7 to 1e-5); over 1e-5 it stays below 5e-7 on
    each of 8 consecutive points of all three orbits tested here."""
    J = np.empty((y.size, y.size))
    for j in range(y.size):
        dy = 1e-5 * smap.scale[j]
        e = np.eye(y.size)[j] * dy
        hi = smap.orbit(y + e, keep=n, mode=mode).final_state
        lo = smap.orbit(y - e, keep=n, mode=mode).final_state
        J[:, j] = (hi - lo) / (2.0 * dy)
    return J


def test_the_tangent_leaves_the_trajectory_unchanged():
    # step-size control sees the state only: same steps, same events, same final state
    for path, sets in ((DUFFING, []), (ROTOR, ROTOR_RUB)):
        system = load_scenario(path, sets).system
        smap = StroboscopicMap(system, 1e-10)
        plain = smap.orbit(keep=30)
        _, impacts, y, mode = monodromy(system, system.y0, 30, system.mode0, 1e-10)
        assert np.array_equal(y, plain.final_state) and mode == plain.mode
        assert impacts == plain.impacts.sum() and impacts > 0


def test_smooth_duffing_exponents_sum_to_minus_the_damping():
    # no contact: Liouville, d(ln det Phi)/dt = tr J = -b (unit mass)
    system = load_scenario(DUFFING, ["oscillator.barrier=100.0"]).system
    lyap = lyapunov_spectrum(system, 200, 50)
    assert lyap.impacts == 0
    assert np.sum(lyap.exponents) == pytest.approx(-0.1, abs=1e-8)
    assert lyap.liouville == pytest.approx(-0.1, abs=1e-8)


def test_each_impact_adds_twice_the_log_restitution():
    # the 1-1 orbit: per period the exponents sum to -b T + 2 ln R (one impact)
    system = load_scenario(DUFFING).system
    lyap = lyapunov_spectrum(system, 200, 100)
    T = math.pi
    assert lyap.impacts == 200
    assert np.sum(lyap.per_interval) == pytest.approx(-0.1 * T + 2.0 * math.log(0.8), abs=1e-7)
    assert lyap.jumps * T == pytest.approx(2.0 * math.log(0.8), abs=1e-7)
    # a stable periodic orbit: both exponents negative, = ln|multipliers| / T
    f = floquet(StroboscopicMap(system, FLOQUET_RTOL), lyap.state, 1)
    expected = np.sort(np.log(np.abs(f.multipliers)))[::-1] / T
    if abs(f.multipliers[0]) == pytest.approx(abs(f.multipliers[1]), rel=1e-9):
        expected = np.full(2, expected.mean())  # a complex pair: one modulus
    assert lyap.exponents == pytest.approx(expected, abs=2e-3)


def test_floquet_product_of_the_impacting_orbit_is_restitution_squared_times_decay():
    system = load_scenario(DUFFING).system
    smap = StroboscopicMap(system, FLOQUET_RTOL)
    f = floquet(smap, smap.orbit(skip=100).final_state, 1)
    assert f.impacts == 1
    assert np.prod(f.multipliers).real == pytest.approx(0.8**2 * math.exp(-0.1 * math.pi), 1e-9)


@pytest.mark.parametrize(
    "path, sets, tol",
    [
        (DUFFING, [], 1e-6),  # rigid impact: the saltation matrix of Newton's law
        # the kink of a piecewise-linear stop at the ends of the steps
        (DUFFING, ['oscillator.stop="elastic_one_sided"', "oscillator.stop_stiffness=30.0"], 1e-6),
        # three penalty contacts with friction: the friction's kink at the contact surface
        # (it follows the compressive normal force) costs about 1e-5 (see reference.tangent)
        (ROTOR, ROTOR_RUB, 1e-4),
    ],
)
def test_variational_monodromy_agrees_with_finite_differences(path, sets, tol):
    system = load_scenario(path, sets).system
    smap = StroboscopicMap(system, FLOQUET_RTOL)
    orbit = smap.orbit(skip=150)
    y, mode = orbit.final_state, int(orbit.mode)
    Phi, impacts, _, _ = monodromy(system, y, 1, mode, FLOQUET_RTOL)
    J = fd_jacobian(smap, y, 1, mode)
    scaled = np.abs(Phi - J) * smap.scale[None, :] / smap.scale[:, None]
    assert impacts >= 1
    assert scaled.max() <= tol * max(1.0, np.abs(J).max())


def test_rotor_on_a_penalty_stator_has_a_zero_exponent_and_the_damping_trace():
    # The centred rotor is symmetric under a rotation by a with a time shift a / w, so
    # xi = (J_R p - v / w, J_R v - a / w) solves the variational equations: one
    # exponent is 0.  Without contact damping only the rotor damps: tr J = -2 c / m.
    system = load_scenario(ROTOR, ROTOR_RUB).system
    lyap = lyapunov_spectrum(system, 300, 200, rtol=1e-10)
    assert lyap.impacts >= 2 * 300
    c_over_m = 316.227766 / 10.0
    assert lyap.liouville == pytest.approx(-2.0 * c_over_m, rel=1e-9)
    assert np.sum(lyap.exponents) == pytest.approx(-2.0 * c_over_m, rel=1e-6)
    T = lyap.interval
    # converges as 1 / periods (0.0075 per period after 2000 periods)
    assert np.min(np.abs(lyap.per_interval)) < 0.05
    p, model = model_of(system)
    w = 2.0 * math.pi / T

    def xi(t: float, y: np.ndarray, mode: int) -> np.ndarray:
        f = full_rhs_alloc(t, y, mode, p, model, None)
        return (np.array([-y[1], y[0], -y[3], y[2]]) - f / w) / system.state_scale

    y0 = lyap.state
    Phi, impacts, y1, m1 = monodromy(system, y0, 2, lyap.mode, 1e-12)
    moved = Phi @ (xi(0.0, y0, lyap.mode) * system.state_scale) / system.state_scale
    assert impacts >= 4
    assert moved == pytest.approx(xi(2 * T, y1, m1), abs=1e-3 * np.abs(moved).max())


def test_lyapunov_refuses_bad_input():
    system = load_scenario(DUFFING).system
    with pytest.raises(AnalysisError, match="--periods"):
        lyapunov_spectrum(system, 0)
    with pytest.raises(AnalysisError, match="--transient"):
        lyapunov_spectrum(system, 10, -1)
    with pytest.raises(AnalysisError, match="units.controller"):
        lyapunov_spectrum(load_scenario(SCENARIOS / "jeffcott_delayed_feedback.toml").system)


def test_cli_lyapunov_prints_the_spectrum_and_the_trace_check(capsys):
    assert main(["lyapunov", str(DUFFING), "--periods", "50", "--transient", "50"]) == 0
    out = capsys.readouterr().out
    assert "per unit time" in out and "Liouville" in out
    assert main(["lyapunov", str(DUFFING), "--periods", "0"]) == 2
    assert "--periods" in capsys.readouterr().err
    delayed = str(SCENARIOS / "jeffcott_delayed_feedback.toml")
    assert main(["lyapunov", delayed, "--periods", "5"]) == 2
    assert "units.controller" in capsys.readouterr().err
