"""Pursuit's trusted ties (rubcosim.analysis.trusted_ties) and the scenario's [basins] table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.cellmap import sample_cells
from rubcosim.analysis.maps import StroboscopicMap
from rubcosim.analysis.trusted_ties import chain_fates, trusted
from rubcosim.cli import main
from rubcosim.errors import ScenarioError

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "feng_yang_attractors.toml"


def test_chain_fates_and_trust_on_a_small_graph():
    # 0 -> 1 -> 2 (anchor, fate 5); 3 -> 4 -> sink; 6 -> 6 (a cycle without an anchor)
    nxt = np.array([1, 2, 2, 4, -1, 0, 6])
    anchor = np.array([-1, -1, 5, -1, -1, -1, -1])
    fate = chain_fates(nxt, anchor, 9)
    assert fate.tolist() == [5, 5, 5, 9, 9, 5, -1]
    safe = np.array([True, False, True, True, True, True, True])
    ok = trusted(nxt, anchor >= 0, safe)
    # 1's tie is unsafe: 1 and everything whose chain goes through it are not trusted
    assert ok.tolist() == [False, False, True, True, True, False, False]


def test_pursuit_sends_every_sample_where_direct_simulation_does():
    """Feng & Yang's case on a coarse grid (thin interleaved basins): each of a random
    set of samples is simulated 800 periods (rtol 1e-9) and classified by where it
    ends; pursuit's fate of the sample must be the same."""
    sc = rc.load(SCENARIO)
    grid, samples = (40, 40), 4
    b = rc.basins(sc, grid, samples, (-2.0, 1.0, -2.0, 2.0), workers=1, method="pursuit")
    assert b.n_attractors == 4
    fates = b.fates.ravel()
    points = sample_cells(b.grid, 0, b.grid.n_cells, samples, 0)
    rng = np.random.default_rng(3)
    pick = rng.choice(np.flatnonzero(fates < b.n_attractors), 100, replace=False)
    ends, _, _, status = StroboscopicMap(sc.system, 1e-9).map(points[pick], periods=800)
    assert np.all(status == 0)
    direct = np.full(pick.size, -1)
    for k, m in enumerate(b.motions):
        if m["periodic"]:
            d = np.max(np.abs(ends - np.asarray(m["poincare_points"][0])), axis=1)
            direct[d < 1e-4] = k
    chaotic = [k for k, m in enumerate(b.motions) if not m["periodic"]]
    direct[direct < 0] = chaotic[0]
    assert np.sum(direct == fates[pick]) == pick.size


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
