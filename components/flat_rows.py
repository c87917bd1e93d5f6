"""The row of a unit in the compiled co-simulation master: its layout and statuses.

A row (:mod:`.flat_units`) holds:

* ``Y`` .. ``Y + 7``: the continuous state (rotor disc and journal, casing; a hybrid
  unit's state, at most six values, then its mode at ``HY_MODE`` and its impact
  count at ``HY_IMPACTS``);
* ``H``: the step size the unit's integrator tries next;
* ``IV``: the rotor's ``resets_applied`` counter;
* ``T``: the unit's time (s);
* ``U + 3 i`` .. ``U + 3 i + 2``: input ``i``'s value, first and second time
  derivative at the step's start (in the order of the unit class's ``inputs``).
"""

from __future__ import annotations

# flat unit kinds (K_PENALTY: a massless stator with any penalty law, K_CASING one on a
# casing, :mod:`.contact_law`; K_BEARING: a bearing with any force law,
# :mod:`.bearing_law`; K_HYBRID: every hybrid unit type, :mod:`.flat_hybrid`;
# K_CONTROLLER: the delayed-feedback controller, its history in a buffer,
# :mod:`.flat_controller`)
K_JEFFCOTT, K_TWO_MASS, K_RIGID, K_PENALTY, K_CASING, K_BEARING, K_HYBRID = range(7)
K_CONTROLLER = 8

Y, H, IV, T, U = 0, 8, 9, 10, 11
HY_MODE, HY_IMPACTS = Y + 6, Y + 7
MAX_INPUTS = 7
ROW = U + 3 * MAX_INPUTS
MAX_OUTPUTS = 11
MAX_PARAMS = 20
# a hybrid unit's parameter row: its kernels' array (inputs from its input_base on),
# then, at the end, which hybrid type it is and that input_base
P_HYBRID, P_INPUT_BASE = MAX_PARAMS - 2, MAX_PARAMS - 1

# what a step or an output evaluation can report
STEP_OK = 0
STEP_BAD_INPUT = 1  # an input is not finite
STEP_FAILED = 2  # the integrator failed (step size below round-off, state not finite)
STEP_NOT_FINITE = 3  # the state is not finite after the step
STEP_NO_ROOM = 7  # a controller's history outgrew its buffer (the master makes room first)
