"""The monolithic reference watches what the co-simulation masters watch: for every
stator contact kind and state, the reference's event functions have the direction and
the rate companion that the masters' table (``components.contact_law.WATCHED``) gives
the stator output, and the value of that output."""

from __future__ import annotations

import numpy as np
import pytest
from test_specialize import _through_the_pointers

from rubcosim.components.contact_law import WATCHED
from rubcosim.components.stator import MODE_FREE, MODE_SLIDE_NEG, MODE_SLIDE_POS, MODE_STICK
from rubcosim.components.units import unit_type
from rubcosim.reference import system as S
from rubcosim.reference.specialize import compiled_model
from rubcosim.scenario import load_scenario

# the reference's event slot of each watched stator output (slot 1 holds the gap's rate)
SLOT = {"gap": 0, "normal_force": 0, "slip": 2, "hold_margin": 2}


@pytest.mark.parametrize(
    "name",
    ["jeffcott_rigid_stator", "jeffcott_elastic_stator", "jeffcott_hunt_crossley_stator"],
)
def test_the_reference_watches_each_stator_output_the_masters_watch(name):
    system = load_scenario(name).system
    kind = unit_type("stator", system.units["stator"].type).contact.kind
    model = compiled_model(system)
    p = np.array(system.p, dtype=float)
    names = system.output_names
    y = system.y0.copy()
    y[0] = 1.01 * system.units["stator"].params["clearance"]  # the disc in the stator
    for mode in (MODE_FREE, MODE_SLIDE_POS, MODE_SLIDE_NEG, MODE_STICK):
        state = mode if kind == "rigid" else int(mode != MODE_FREE)
        g = np.zeros(S.N_EVENTS)
        dirs, rates = np.zeros(S.N_EVENTS, np.int64), np.zeros(S.N_EVENTS, np.int64)
        out = np.zeros(len(names))
        _through_the_pointers(model, 0.0, y, np.zeros(S.N_DELAYED), mode, p, g, dirs, rates, out)
        for output, direction, _, rate in WATCHED[kind][state]:
            slot = SLOT[output]
            assert dirs[slot] == direction, (mode, output)
            assert rates[slot] == (1 if rate else -1), (mode, output)
            if f"stator.{output}" in names:
                assert g[slot] == pytest.approx(out[names.index(f"stator.{output}")], rel=1e-12)
