"""Verified neighbourhoods (analysis.state_space.within_radius): whether a state lies in
a ball around an attractor's points, against a direct comparison with every point."""

from __future__ import annotations

import numpy as np

from rubcosim.analysis.state_space import nearest_spacings, within_radius


def _direct(z: np.ndarray, pts: np.ndarray, radius: float) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        d = np.max(np.abs(z[:, None, :] - pts[None, :, :]), axis=2)
    return np.any(d <= radius, axis=1)


def _search(z: np.ndarray, pts: np.ndarray, radius: float) -> np.ndarray:
    hit = np.zeros(z.shape[0], dtype=bool)
    within_radius(z, np.ascontiguousarray(pts[np.argsort(pts[:, 0])]), radius, hit)
    return hit


def test_balls_around_many_points_equal_the_direct_comparison():
    rng = np.random.default_rng(5)
    pts = rng.uniform(-1, 1, (2000, 3))
    z = np.vstack([rng.uniform(-1.1, 1.1, (5000, 3)), pts + rng.uniform(-2e-3, 2e-3, pts.shape)])
    for radius in (1e-3, 2e-2, 0.3):
        hit = _search(z, pts, radius)
        assert np.array_equal(hit, _direct(z, pts, radius))
        assert 0 < hit.sum() < z.shape[0] or radius == 0.3  # the largest covers all


def test_the_ball_is_closed_and_states_that_are_not_finite_are_outside():
    pts = np.array([[0.0, 0.0], [0.5, 0.25]])
    z = np.array([[0.125, 0.0], [0.5, 0.375], [0.5 + 0.125, 0.25], [np.nan, 0.0], [np.inf, 0.0]])
    assert _search(z, pts, 0.125).tolist() == [True, True, True, False, False]
    assert _search(z, pts, np.nextafter(0.125, 0.0)).tolist() == [False] * 5


def test_nearest_spacings_equal_a_k_d_tree_query():
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(11)
    pts = np.vstack([rng.standard_normal((1500, 2)), [[0.5, 0.5], [0.5, 0.5]]])  # a pair
    pts = np.ascontiguousarray(pts[np.argsort(pts[:, 0])])
    d, _ = cKDTree(pts).query(pts, k=2, p=np.inf)
    assert np.array_equal(nearest_spacings(pts), d[:, 1])
