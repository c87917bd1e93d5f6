"""Basins by pursuit (``--method pursuit``) on Feng & Yang's case, on a coarse grid."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rubcosim.analysis.sample_graph import cycle_members, terminal_cycles
from rubcosim.cli import main

SCENARIO = Path(__file__).resolve().parent.parent / "scenarios" / "feng_yang_attractors.toml"
# The paper's grid: 200 x 200 cells over [-2, 1] x [-2, 2], Hsu's z = (j - 1) 200 + i
DX, DV = 3.0 / 200, 4.0 / 200


def paper_centre(zs):
    """Mean (x, x') centre of the paper's cells, from its numbering alone."""
    j, i = np.divmod(np.asarray(zs) - 1, 200)
    return np.array([np.mean(-2.0 + (i + 0.5) * DX), np.mean(-2.0 + (j + 0.5) * DV)])


PAPER_PERIODIC = {"P2": [15579], "P3": [25185], "P4": [23398]}
PAPER_CHAOTIC = [13950, 14147, 14148, 14149, 14150, 14347]
PAPER_SADDLES = {"S1": [13164], "S2": [20188]}


def near(points, centre, cells=1.5):
    """Whether some point lies within ``cells`` of the paper's cell widths of ``centre``."""
    d = np.abs(np.atleast_2d(points) - centre) / np.array([DX, DV])
    return bool(np.any(np.all(d <= cells, axis=1)))


def test_terminal_cycles_of_a_functional_graph():
    # 0 -> 1 -> 2 -> 1 (cycle {1, 2}); 3 -> 4 -> sink; 5 -> 5; 6 -> 0
    nxt = np.array([1, 2, 1, 4, -1, 5, 0])
    term = terminal_cycles(nxt)
    assert term[3] == term[4] == -1 and term[5] == 5
    assert term[0] == term[1] == term[2] == term[6] and term[0] in (1, 2)
    assert sorted(cycle_members(nxt, int(term[0]))) == [1, 2]


def test_pursuit_finds_feng_yangs_four_attractors_and_two_saddles(tmp_path, capsys):
    out = tmp_path / "fy"
    args = ["basins", str(SCENARIO), "--method", "pursuit", "--grid", "60x80"]
    args += ["--samples", "4", "--region=-2:1,-2:2", "--workers", "1", "--no-progress"]
    assert main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "4 attractor(s)" in printed and "S1" in printed
    report = json.loads((out / "report.json").read_text())
    atts = report["attractors"]
    assert len(atts) == 4 and report["method"] == "pursuit"
    periodic = [a for a in atts if a["periodic"]]
    chaotic = [a for a in atts if not a["periodic"]]
    assert len(periodic) == 3 and len(chaotic) == 1
    assert chaotic[0]["label"] == "chaotic or quasi-periodic"
    for name, zs in PAPER_PERIODIC.items():
        hits = [a for a in periodic if near(a["poincare_points"], paper_centre(zs))]
        assert len(hits) == 1, name
        assert hits[0]["period"] == 1
    assert near(chaotic[0]["section_points"], paper_centre(PAPER_CHAOTIC), cells=1.0)
    saddles = [p for p in report["fixed_points"] if p["saddle"]]
    for name, zs in PAPER_SADDLES.items():
        hits = [p for p in saddles if near(p["state"], paper_centre(zs))]
        assert len(hits) == 1, name
        moduli = np.abs(np.array([complex(*z) for z in hits[0]["multipliers"]]))
        assert np.sum(moduli > 1.0) == 1, name
    # every sample goes somewhere: the attractors' shares and the sink's add up
    s = report["samples"]
    assert s["total"] == 60 * 80 * 4
    assert sum(s["fraction_per_attractor"]) + s["sink_fraction"] == pytest.approx(1.0)
    counts = report["counts"]
    assert sum(counts["basins"]) + counts["boundary"] + counts["escape"] == 60 * 80
    assert "published" in report and len(report["published"]["attractors"]) == 4
    # the chaotic attractor is labelled by its largest exponent: positive (the
    # paper's chaos; +0.052 1/s by benchmarks/study_lyapunov.py over 20,000 periods)
    p1 = next(r for r in report["published"]["attractors"] if r["paper"] == "P1")
    assert 0.02 < p1["lyapunov"] < 0.09
    assert f"largest Lyapunov exponent {p1['lyapunov']:+.4f} 1/s" in printed
    assert (out / "basins.png").stat().st_size > 0
    data = np.load(out / "basins.npz")
    assert data["labels"].shape == (4800,)
    for bad, msg in [
        (["--method", "bogus"], "--method"),
        (["--samples", "0"], "--samples"),
        (["--grid", "0x4"], "--grid"),
        (["--region", "1:0,0:1"], "--region"),
    ]:
        assert main([*args, *bad, "--out", str(tmp_path / "bad")]) == 2, bad
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) <= 3, (bad, err)


def test_pursuit_agrees_with_cell_mapping_on_two_well_separated_attractors():
    import rubcosim as rc
    from rubcosim.analysis.errors import AnalysisError

    duffing = SCENARIO.parent / "impact_duffing.toml"
    two_well = ['oscillator.stop="none"', "oscillator.forcing_amplitude=2.0"]
    sc = rc.load(duffing, two_well)
    args = ((30, 30), 4, (-2.0, 4.0, -4.0, 4.0))
    gcm = rc.basins(sc, *args, workers=1, method="gcm")
    pur = rc.basins(sc, *args, workers=1, method="pursuit")
    assert gcm.n_attractors == pur.n_attractors == 2 and pur.info["method"] == "pursuit"
    for m in pur.motions:  # the same two 1-0 orbits (found by direct simulation)
        assert m["label"] == "1-0"
        found = [
            np.allclose(m["poincare_points"][0], g["poincare_points"][0], atol=1e-3)
            for g in gcm.motions
        ]
        assert sum(found) == 1
    # a cell the graph puts in one basin has that attractor's samples, or the sink's
    for k in range(2):
        cells = pur.labels == k
        assert np.all(pur.shares[cells, k] + pur.shares[cells, -1] == pytest.approx(1.0))
    with pytest.raises(AnalysisError, match="--method"):
        rc.basins(sc, *args, method="hsu")
