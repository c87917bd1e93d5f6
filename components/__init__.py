"""Physics of every unit, written once.

Each module declares its unit's parameters (:mod:`.parameters`) and provides
numba-compiled kernels: forces, impact maps, constraint forces.  The reference
integrator, the FMU wrappers and the orchestrator call these kernels; nothing
else writes an equation of motion.
"""

from . import registry  # noqa: F401  (built on import: .registered hands its types down)
from .parameters import Param, ParameterError

__all__ = ["Param", "ParameterError"]
