"""A basins result checks itself: sampled fates against direct simulation
(rubcosim/analysis/fate_check.py), and the default method is the one that passes it on
Feng & Yang's case."""

from __future__ import annotations

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis.errors import AnalysisError
from rubcosim.analysis.fate_check import classify, predicted

ARGS = ((60, 80), 4)  # Feng & Yang's region (the scenario's [basins] table), coarser


@pytest.fixture(scope="module")
def feng_yang():
    return rc.load("feng_yang_attractors")


def test_cell_mapping_on_feng_yang_is_contradicted_by_direct_simulation(feng_yang):
    # the map is close to the identity: cells mix the basins, and cell mapping gives
    # samples to attractors they do not reach; the check says so
    b = rc.basins(feng_yang, *ARGS, workers=1, method="gcm", check=60)
    check = b.info["fate_check"]
    assert check["checked"] == 60 and check["agree"] < 55
    assert check["disagree"] and {"point", "result", "direct"} <= set(check["disagree"][0])


def test_the_default_pursues_every_sample_and_direct_simulation_confirms_it():
    # the paper's parameters on the impact Duffing scenario, which has no [basins] table
    paper = {
        "oscillator.damping": 0.02,
        "oscillator.forcing_amplitude": 0.77,
        "oscillator.forcing_frequency": 0.678,
    }
    sc = rc.load("impact_duffing", set=paper)
    assert not sc.basins
    b = rc.basins(sc, *ARGS, (-2.0, 1.0, -2.0, 2.0), workers=1, check=60)
    assert b.info["method"] == "pursuit" and b.n_attractors == 4
    check = b.info["fate_check"]
    assert check["checked"] == check["agree"] == 60 and check["disagree"] == []


def test_the_classifier_puts_end_states_on_the_orbit_they_sit_on():
    motions = [
        {"label": "1-0", "period": 1, "poincare_points": [[0.5, 0.1]]},
        {"label": "2-1", "period": 2, "poincare_points": [[-1.0, 0.0], [1.0, 0.3]]},
        {"label": "chaotic or quasi-periodic", "period": 0, "periodic": False,
         "poincare_points": [[0.0, 0.0]]},
    ]  # fmt: skip
    ends = np.array([[0.5, 0.1 + 1e-5], [1.0, 0.3], [0.3, -0.7], [np.nan, np.nan]])
    found = classify(ends, motions, np.array([1.0, 1.0]))
    assert found.tolist() == [0, 1, 2, -1]
    # without a non-periodic attractor, an end state on no orbit has no fate
    assert classify(ends[2:3], motions[:2], np.array([1.0, 1.0])).tolist() == [-1]


def test_predicted_fates_leave_out_the_sink_and_boundary_cells(feng_yang):
    b = rc.basins(feng_yang, (6, 8), 1, workers=1, method="gcm", check=0)
    assert "fate_check" not in b.info
    fate = predicted(b)
    assert fate.shape == (48,) and set(np.unique(fate)) <= {-1, *range(b.n_attractors)}
    assert np.all(fate[b.labels < 0] == -1)


def test_a_negative_check_count_names_the_flag(feng_yang):
    with pytest.raises(AnalysisError, match="--check"):
        rc.basins(feng_yang, (6, 8), 1, workers=1, check=-1)


def test_basin_fates_check_classifies_end_states_by_the_orbit_they_end_on():
    # (moved from test_benchmark_scripts: verify_basin_fates classifies with this
    # function; at state scales 0.1, AT_ORBIT = 1e-3 scales is its 1e-4 in state units)
    motions = [
        {"periodic": True, "poincare_points": [[0.5, 0.5]]},
        {"periodic": False},
        {"periodic": True, "poincare_points": [[1.0, 0.0], [-1.0, 0.0]]},  # period 2
    ]
    scale = np.array([0.1, 0.1])
    ends = np.array([[0.5, 0.5 + 5e-5], [0.5, 0.5 + 5e-4], [-1.0 + 1e-5, 0.0], [1.0, 0.0]])
    assert list(classify(ends, motions, scale)) == [0, 1, 2, 2]
    assert list(classify(ends, motions[:1], scale)) == [0, -1, -1, -1]  # no other attractor
