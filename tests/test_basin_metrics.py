"""Basin metrics (:mod:`rubcosim.analysis.basin_metrics`) on basins made by hand, whose
values are known exactly: a straight boundary, a Sierpinski carpet, an uncorrelated
three-colour basin (its expected basin entropy by enumeration), three stripes."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.basin_metrics import basin_metrics, boundary_dimension, box_entropy


def _h(p: float) -> float:
    return -p * math.log(p) - (1 - p) * math.log(1 - p)


def test_a_straight_boundary_has_the_entropy_of_its_split_and_dimension_one():
    """Outcome 0 left of column 52, 1 from it: the boxes of 5 x 5 cells across the
    boundary (columns 50-54) hold 2 / 5 of outcome 0, so Sbb = H(0.4) exactly, Sb is that
    over the 20 box columns, the ln 2 criterion is silent, and the boundary's dimension
    is 1 (the uncertainty exponent 1 within 0.1)."""
    grid = np.zeros((100, 100), dtype=int)
    grid[:, 52:] = 1
    sb, sbb, boxes, mixed = box_entropy(grid[:, :, None], 5)
    assert (boxes, mixed) == (400, 20)
    assert sbb == pytest.approx(_h(0.4), abs=1e-15)
    assert sb == pytest.approx(_h(0.4) / 20, abs=1e-15)
    wide = np.zeros((200, 200), dtype=int)
    wide[:, 53:] = 1
    m = basin_metrics(wide)
    assert not m["basin_entropy"]["ln2_criterion_fractal"]
    assert abs(m["boundary"]["uncertainty_exponent"] - 1.0) < 0.1
    assert m["basin_stability"] == {"0": 53 / 200, "1": 147 / 200}


def _carpet(level: int) -> np.ndarray:
    """Sierpinski carpet of 3^level cells a side: 1 in its holes, 0 on the carpet."""
    n = 3**level
    i = np.arange(n)
    hole = np.zeros((n, n), dtype=bool)
    for k in range(level):
        a = (i // 3**k) % 3 == 1
        hole |= a[:, None] & a[None, :]
    return hole.astype(int)


def test_a_sierpinski_carpets_boundary_has_dimension_ln8_over_ln3():
    """Aligned boxes of 3^k cells holding both colours are the carpet's 8^(5-k) blocks
    of that size: the dimension is ln 8 / ln 3 exactly, the exponent 2 minus it."""
    d = boundary_dimension(_carpet(5), sizes=np.array([3, 9, 27, 81]))
    assert d["boundary_boxes"] == [8**4, 8**3, 8**2, 8]
    assert d["dimension"] == pytest.approx(math.log(8) / math.log(3), abs=1e-12)
    assert d["uncertainty_exponent"] == pytest.approx(2 - math.log(8) / math.log(3), abs=1e-12)


def test_an_uncorrelated_three_colour_basin_has_the_enumerated_entropy_and_is_wada():
    """Each cell one of three outcomes at random: a box of 2 x 2 cells has the expected
    entropy of four independent draws (enumerated over the 81 cases); Sbb > ln 2 (the
    criterion fires), every boundary is within three cells of every other (Wada), and
    the boundary fills the plane (exponent near 0)."""
    rng = np.random.default_rng(1)
    grid = rng.integers(0, 3, size=(400, 400))
    expected = []
    for case in itertools.product(range(3), repeat=4):
        p = np.bincount(case, minlength=3) / 4
        expected.append(-sum(q * math.log(q) for q in p if q > 0))
    mean, sd = float(np.mean(expected)), float(np.std(expected))
    sb, sbb, boxes, _ = box_entropy(grid[:, :, None], 2)
    assert abs(sb - mean) < 5 * sd / math.sqrt(boxes)
    m = basin_metrics(grid)
    assert m["basin_entropy"]["Sbb"] > math.log(2) and m["basin_entropy"]["ln2_criterion_fractal"]
    assert m["wada"]["wada"] and m["wada"]["max_distance_cells"] <= 3.0
    assert abs(m["boundary"]["uncertainty_exponent"]) < 0.1


def test_three_stripes_are_not_wada():
    """0 | 1 | 2 in bands of 30 cells: the boundary of 0 (columns 29, 30) is 30 cells
    from that of 2 (columns 59, 60)."""
    grid = np.repeat(np.repeat(np.arange(3), 30)[None, :], 90, axis=0)
    w = basin_metrics(grid)["wada"]
    assert not w["wada"] and w["distances_cells"]["0->2"] == pytest.approx(30.0)
    assert not basin_metrics(grid)["basin_entropy"]["ln2_criterion_fractal"]


def test_a_basins_result_reports_its_metrics():
    """Wiring: rc.basins(...).metrics() on every sample's fate; shares sum to one."""
    b = rc.basins("impact_duffing", grid=(24, 24), samples=2, region=(-3, 1, -6, 6))
    m = b.metrics()
    assert m["from"] == "every sample's fate"
    assert sum(m["basin_stability"].values()) == pytest.approx(1.0)
    assert set(m) >= {"basin_entropy", "boundary", "wada"}


def test_a_grid_smaller_than_a_box_still_gets_its_other_metrics():
    m = basin_metrics(np.array([[0, 1], [1, 2]]))
    assert "larger than the grid" in m["basin_entropy"]["error"]
    assert "error" in m["boundary"] and m["basin_stability"]["1"] == 0.5
