"""The grid's nearest-sample search against a k-d tree (a second method)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rubcosim.analysis.cellmap import Grid, all_samples
from rubcosim.analysis.sample_index import SampleIndex


@pytest.mark.parametrize(
    ("grid", "samples", "k"),
    [("40x30", 16, 8), ("25x25", 1, 8), ("7x5", 2, 12), ("3x1", 1, 3)],
)
def test_nearest_samples_are_the_k_d_trees(grid, samples, k):
    """The same neighbours, nearest first, as cKDTree in cell-width units: inside, on
    the region's edges and corners, with one sample per cell (the search goes out
    several rings) and on a grid one cell high."""
    g = Grid.parse(grid, "-2:1,-2:2")
    pts = all_samples(g, samples, seed=5, chunk=7)
    rng = np.random.default_rng(1)
    q = np.column_stack((rng.uniform(-2, 1, 3000), rng.uniform(-2, 2, 3000)))
    eps = 1e-12
    edges = [[-2, -2], [1 - eps, 2 - eps], [-2, 2 - eps], [1 - eps, -2], [-0.5, -2], [-2, 0.1]]
    q = np.vstack((q, edges))
    k = min(k, pts.shape[0])
    got = SampleIndex(g, pts, samples).query(q, k)
    cell = np.array([g.dx, g.dv])
    d_tree, want = cKDTree(pts / cell).query(q / cell, k=k)
    assert got.shape == (q.shape[0], k)
    # equal up to the order of equal distances: compare the distances they give
    d_got = np.linalg.norm((pts[got] - q[:, None, :]) / cell, axis=2)
    np.testing.assert_allclose(d_got, np.asarray(d_tree).reshape(q.shape[0], k), rtol=1e-12)
    assert np.mean(np.all(got == np.asarray(want).reshape(q.shape[0], k), axis=1)) > 0.999


def test_sample_index_refuses_what_it_cannot_answer():
    g = Grid.parse("4x4", "0:1,0:1")
    pts = all_samples(g, 3, seed=0)
    with pytest.raises(ValueError, match="expected 16 cells x 2 samples"):
        SampleIndex(g, pts, 2)
    with pytest.raises(ValueError, match="outside the region"):
        SampleIndex(g, pts, 3).query(np.array([[0.5, 1.5]]), 2)
