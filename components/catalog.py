"""Which unit types exist, by role, and their declared parameters."""

from __future__ import annotations

from .bearing import LINEAR_PARAMS, OILFILM_PARAMS
from .controller import CONTROLLER_PARAMS
from .oscillator import OSCILLATOR_PARAMS
from .parameters import Param
from .rotor import JEFFCOTT_PARAMS, TWO_MASS_PARAMS
from .stator import CASING_PARAMS, ELASTIC_PARAMS, RIGID_PARAMS

UNIT_TYPES: dict[str, dict[str, tuple[Param, ...]]] = {
    "rotor": {"jeffcott": JEFFCOTT_PARAMS, "two_mass": TWO_MASS_PARAMS},
    "stator": {"rigid": RIGID_PARAMS, "elastic": ELASTIC_PARAMS, "casing": CASING_PARAMS},
    "bearing": {"oilfilm": OILFILM_PARAMS, "linear": LINEAR_PARAMS},
    "controller": {"delayed_feedback": CONTROLLER_PARAMS},
    "oscillator": {"impact_oscillator": OSCILLATOR_PARAMS},
}
