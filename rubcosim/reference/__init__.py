"""Monolithic reference: every unit in one event-driven system, two engines.

``simulate(system, t_end, engine="accurate" | "fast")``; build the system with
:func:`build_system` from validated units (:func:`make_unit`), or from a
scenario file with :func:`rubcosim.scenario.load_scenario`.
"""

from rubcosim.components.graph import UnitNode as Unit
from rubcosim.components.graph import make_node as make_unit

from .assemble import System, build_system
from .simulate import Events, Result, output_grid, simulate

__all__ = [
    "Events",
    "Result",
    "System",
    "Unit",
    "build_system",
    "make_unit",
    "output_grid",
    "simulate",
]
