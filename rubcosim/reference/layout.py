"""Layout of an assembled system's arrays, shared by :mod:`.system` and its families.

``ip`` (integers) says which units a system has and where their states are;
``p`` (reals) holds every parameter in SI units, at the slots named here.
Event kinds name what an event did (:data:`KIND_NAMES`).  Re-exported by
:mod:`.system`, where the rest of the package reads them.
"""

from __future__ import annotations

# Event kinds and the number of event slots are shared with the hybrid unit types.
from rubcosim.components.hybrid_dispatch import (  # noqa: F401
    KIND_BREAK,
    KIND_CONTACT_OFF,
    KIND_CONTACT_ON,
    KIND_IMPACT,
    KIND_NAMES,
    KIND_RELEASE,
    KIND_SLIP,
    N_EVENTS,
)

FAMILY_ROTOR = 0
FAMILY_HYBRID = 1  # hybrid unit type i (rubcosim.components.hybrid_dispatch) is 1 + i

# ip layout
IP_FAMILY = 0
IP_ROTOR = 1  # 0 jeffcott, 1 two-mass
IP_STATOR = 2  # 0 none, 1 rigid, 2 elastic, 3 casing
IP_BEARING = 3  # 0 none, 1 linear, 2 oil film
IP_CONTROL = 4  # 0 none, 1 position feedback, 2 velocity feedback
IP_NSTATE = 5
IP_JOURNAL = 6  # state offset of the journal, -1 if none
IP_CASING = 7  # state offset of the casing, -1 if none
N_IP = 8

ROTOR_JEFFCOTT, ROTOR_TWO_MASS = 0, 1
STATOR_NONE, STATOR_RIGID, STATOR_ELASTIC, STATOR_CASING = 0, 1, 2, 3
BEARING_NONE, BEARING_LINEAR, BEARING_OILFILM = 0, 1, 2
CONTROL_NONE, CONTROL_POSITION, CONTROL_VELOCITY = 0, 1, 2

# p layout, rotor family
P_M, P_C, P_K, P_E, P_W, P_G, P_RD = 0, 1, 2, 3, 4, 5, 6
P_MJ, P_CJ, P_CSH = 7, 8, 9
P_D, P_X0, P_Y0, P_R, P_MU, P_KC, P_CC = 10, 11, 12, 13, 14, 15, 16
P_MS, P_KS, P_CSC = 17, 18, 19
P_KB, P_CB, P_SIGMA, P_CR = 20, 21, 22, 23
P_KCTL, P_TAU0, P_EPS, P_NU, P_TON = 24, 25, 26, 27, 28
# shared
P_VCHAT = 29  # normal speed below which a rebound counts as settled (chattering ends), m/s
P_OMEGA_B = 30  # Baumgarte rate of the sustained-contact constraint, rad/s
N_P = 32

# Rotor modes MODE_FREE, MODE_SLIDE_POS, MODE_SLIDE_NEG, MODE_STICK: components.stator.
# The impact oscillator's modes: stuck on the barrier +D / -D (free: MODE_FREE = 0)
from rubcosim.components.oscillator_unit import (  # noqa: E402, F401
    STUCK_LOWER as MODE_STUCK_LOWER,
)
from rubcosim.components.oscillator_unit import (  # noqa: E402, F401
    STUCK_UPPER as MODE_STUCK_UPPER,
)

N_DELAYED = 4  # the controller feeds back the disc state (x, y, vx, vy)
