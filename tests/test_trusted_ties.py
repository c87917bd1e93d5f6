"""Pursuit's trusted ties (rubcosim.analysis.trusted_ties) and the scenario's [basins] table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.cellmap import sample_cells
from rubcosim.analysis.maps import StroboscopicMap
from rubcosim.analysis.tie_passes import (
    dependency_order,
    fates_in_order,
    safe_ties,
    successor_positions,
    trust_in_order,
)
from rubcosim.cli import main
from rubcosim.errors import ScenarioError

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "feng_yang_attractors.toml"


def _passes(nxt, anchor, near, sink):
    """Fate, safety and trust by the one-pass functions over the dependency order."""
    n = nxt.shape[0]
    order, reached = dependency_order(nxt, anchor >= 0)
    succ = successor_positions(order, nxt)
    fate, safe, ok = np.empty(n, dtype=np.int64), np.empty(n, dtype=bool), np.empty(n, dtype=bool)
    fates_in_order(order, reached, succ, anchor, sink, -1, fate)
    safe_ties(nxt, near, fate, safe)
    trust_in_order(order, reached, succ, anchor, safe, ok)
    return order, fate, safe, ok


def _walk(nxt, anchor, near, sink):
    """The same by following every chain to its end (plain Python, a second method)."""
    n = nxt.shape[0]
    fate = np.empty(n, dtype=np.int64)
    ok = np.empty(n, dtype=bool)
    for s in range(n):
        u, seen = s, set()
        while u >= 0 and anchor[u] < 0 and u not in seen:
            seen.add(u)
            u = nxt[u]
        fate[s] = sink if u < 0 else (anchor[u] if anchor[u] >= 0 else -1)
    safe = np.array(
        [nxt[u] < 0 or (fate[near[u, 0]] >= 0 and np.all(fate[near[u]] == fate[near[u, 0]]))
         for u in range(n)]
    )  # fmt: skip
    for s in range(n):
        u, seen, good = s, set(), True
        while u >= 0 and anchor[u] < 0 and u not in seen:
            seen.add(u)
            good = good and bool(safe[u])
            u = nxt[u]
        ok[s] = good and (u < 0 or anchor[u] >= 0)
    return fate, safe, ok


def test_fates_and_trust_on_a_small_graph():
    # 0 -> 1 -> 2 (anchor, fate 5); 3 -> 4 -> sink; 5 -> 0; 6 -> 6 (a cycle without an anchor)
    nxt = np.array([1, 2, 2, 4, -1, 0, 6])
    anchor = np.array([-1, -1, 5, -1, -1, -1, -1])
    near = np.array([[2, 1], [0, 3], [1, 0], [4, 3], [0, 0], [0, 1], [6, 6]])
    order, fate, safe, ok = _passes(nxt, anchor, near, 9)
    assert fate.tolist() == [5, 5, 5, 9, 9, 5, -1]
    # 1's image lies between a sample going to 5 and one going to the sink: unsafe
    assert safe.tolist() == [True, False, True, True, True, True, False]
    # 1's tie is unsafe: 1 and everything whose chain goes through it are not trusted
    assert ok.tolist() == [False, False, True, True, True, False, False]
    position = np.argsort(order)
    for u in range(7):  # each sample after its successor, the anchors' successors aside
        if anchor[u] < 0 and nxt[u] >= 0 and u != 6:
            assert position[nxt[u]] < position[u]


@pytest.mark.parametrize("seed", range(4))
def test_one_pass_fates_and_trust_agree_with_following_every_chain(seed):
    # random functional graphs with sinks, anchors and cycles (some without an anchor)
    rng = np.random.default_rng(seed)
    n = 400
    nxt = rng.integers(-1, n, n)
    nxt[rng.random(n) < 0.05] = -1
    anchor = np.where(rng.random(n) < 0.03, rng.integers(0, 3, n), -1)
    near = rng.integers(0, n, (n, 3))
    near[:, 1] = np.where(rng.random(n) < 0.7, near[:, 0], near[:, 1])
    near[:, 2] = np.where(rng.random(n) < 0.7, near[:, 0], near[:, 2])
    _, fate, safe, ok = _passes(nxt, anchor, near, 7)
    f_ref, s_ref, ok_ref = _walk(nxt, anchor, near, 7)
    assert np.array_equal(fate, f_ref)
    assert np.array_equal(safe, s_ref)
    assert np.array_equal(ok, ok_ref)
    assert 0 < ok.sum() < n and (fate == -1).any()  # the draw covers every case


def test_pursuit_sends_every_sample_where_direct_simulation_does(monkeypatch):
    """Feng & Yang's case on a coarse grid (thin interleaved basins): each of a random
    set of samples is simulated 800 periods (rtol 1e-9) and classified by where it
    ends; pursuit's fate of the sample must be the same.  Also with the trust passes
    run every ``PASS_EVERY`` rounds from the first round (as they are once few samples
    are tracked): a tie made unsafe between two passes must still be tracked."""
    from rubcosim.analysis import trusted_ties

    sc = rc.load(SCENARIO)
    grid, samples = (40, 40), 4
    region = (-2.0, 1.0, -2.0, 2.0)
    b = rc.basins(sc, grid, samples, region, workers=1, method="pursuit")
    monkeypatch.setattr(trusted_ties, "FEW_TRACKED", 1)  # lazy whenever any is tracked
    lazy = rc.basins(sc, grid, samples, region, workers=1, method="pursuit")
    ties = lazy.info["pursuit"]["ties"]
    assert ties["trust_passes"] < ties["rounds"]  # passes were skipped
    assert b.n_attractors == lazy.n_attractors == 4
    points = sample_cells(b.grid, 0, b.grid.n_cells, samples, 0)
    rng = np.random.default_rng(3)
    pick = rng.choice(np.flatnonzero(b.fates.ravel() < b.n_attractors), 100, replace=False)
    ends, _, _, status = StroboscopicMap(sc.system, 1e-9).map(points[pick], periods=800)
    assert np.all(status == 0)
    direct = np.full(pick.size, -1)
    for k, m in enumerate(b.motions):
        if m["periodic"]:
            d = np.max(np.abs(ends - np.asarray(m["poincare_points"][0])), axis=1)
            direct[d < 1e-4] = k
    chaotic = [k for k, m in enumerate(b.motions) if not m["periodic"]]
    direct[direct < 0] = chaotic[0]
    assert np.sum(direct == b.fates.ravel()[pick]) == pick.size
    # the same attractors in the same order (found from the same samples)
    assert [m["label"] for m in lazy.motions] == [m["label"] for m in b.motions]
    assert np.sum(direct == lazy.fates.ravel()[pick]) == pick.size


def test_the_scenario_basins_table_gives_the_defaults(tmp_path, capsys):
    sc = rc.load(SCENARIO)
    assert sc.basins == {
        "method": "pursuit",
        "grid": (200, 200),
        "samples": 16,
        "region": (-2.0, 1.0, -2.0, 2.0),
        "seed": 0,
    }
    data = {**sc.data, "basins": {"method": "gcm", "grid": "6x6", "samples": 1}}
    data["basins"]["region"] = "-2:1,-2:2"
    b = rc.basins(data, workers=1)  # everything from the table
    assert b.info["method"] == "gcm" and b.grid.nx == 6 and b.samples == 1
    b = rc.basins(data, (4, 5), workers=1, method="pursuit")  # arguments override it
    assert b.info["method"] == "pursuit" and (b.grid.nx, b.grid.nv) == (4, 5)
    for key, value in [
        ("method", "hsu"),
        ("grid", [0, 4]),
        ("grid", "20"),
        ("samples", 0),
        ("seed", -1),
        ("region", [1, 0, 0, 1]),
        ("region", "a:b"),
        ("slice", "oscillator.x"),
        ("bogus", 1),
    ]:
        with pytest.raises(ScenarioError, match=f"basins.{key}"):
            rc.load({**sc.data, "basins": {key: value}})
    # the command line without --grid on a scenario without basins.grid: one line
    plain = SCENARIO.parent / "impact_duffing.toml"
    args = ["basins", str(plain), "--samples", "1", "--region=-2:1,-2:2"]
    assert main([*args, "--out", str(tmp_path / "x"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "--grid" in err and "basins.grid" in err and len(err.strip().splitlines()) == 1


def test_images_split_over_two_workers_come_back_in_row_order() -> None:
    """Wiring: ``parallel_images`` interleaves a batch's rows over its workers and puts
    the images back in order, the same as one in-process ``map`` of the batch."""
    from rubcosim.analysis.maps import StroboscopicMap
    from rubcosim.analysis.parallel import SPLIT_MIN, parallel_images
    from rubcosim.scenario import load_scenario

    smap = StroboscopicMap(load_scenario("feng_yang_attractors").system, rtol=1e-7)
    rng = np.random.default_rng(3)
    rows = 2 * SPLIT_MIN + 3  # uneven: the workers get different row counts
    states = np.column_stack([rng.uniform(-2, 1, rows), rng.uniform(-2, 2, rows)])
    with parallel_images(smap, workers=2) as images:
        split = images(states)
    np.testing.assert_array_equal(split, smap.map(states)[0])
