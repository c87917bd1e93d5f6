"""The FMI calls a master makes on every macro step, straight to the FMU's C functions.

fmpy's methods (``FMU2Slave.setReal`` and the like) build new ctypes arrays from
Python lists and go through a logging wrapper on every call: a couple of
microseconds each, on calls that cost a few microseconds in all.  A
:class:`ValueCall` makes the value references, orders and value buffer of one
call once and calls the library's function itself; a failed call raises fmpy's
own :class:`~fmpy.fmi1.FMICallException`, as fmpy's methods do.  Everything else
(instantiation, parameters, other types) stays with fmpy.
"""

from __future__ import annotations

import ctypes
from collections.abc import Sequence
from typing import Any

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2FMUstate, fmi2Integer, fmi2Real, fmi2True, fmi2ValueReference

FMI2_WARNING = 1  # statuses above it are failures (fmpy raises from fmi2Discard on)


def check(function: str, status: int) -> None:
    """Raise as fmpy does for a status worse than ``fmi2Warning``."""
    if status > FMI2_WARNING:
        raise FMICallException(function=function, status=status)


class ValueCall:
    """One of ``fmi2GetReal``, ``fmi2SetReal``, ``fmi2SetRealInputDerivatives`` or
    ``fmi2GetInteger`` (``ctype`` fmi2Integer) on fixed value references (and derivative
    ``orders``) of an instantiated fmpy ``FMU2Slave``."""

    def __init__(
        self,
        fmu: Any,
        function: str,
        refs: Sequence[int],
        orders: Sequence[int] = (),
        ctype: Any = fmi2Real,
    ) -> None:
        n = len(refs)
        self.function = function
        self._f = fmu._functions[function]  # the library's function, argument types set
        self._component = fmu.component
        self._n = n
        self._refs = (fmi2ValueReference * n)(*refs)
        self._values = (ctype * n)()
        self._orders = (fmi2Integer * n)(*orders) if orders else None

    def get(self) -> list[Any]:
        check(self.function, self._f(self._component, self._refs, self._n, self._values))
        return self._values[:]

    def set(self, values: Sequence[float]) -> None:
        self._values[:] = values
        if self._orders is None:
            status = self._f(self._component, self._refs, self._n, self._values)
        else:
            status = self._f(self._component, self._refs, self._n, self._orders, self._values)
        check(self.function, status)


class StepCalls:
    """``fmi2DoStep`` and the rollback calls of an instantiated fmpy ``FMU2Slave``."""

    def __init__(self, fmu: Any) -> None:
        self._component = fmu.component
        f = fmu._functions
        self._do_step = f["fmi2DoStep"]
        self._get_state = f["fmi2GetFMUstate"]
        self._set_state = f["fmi2SetFMUstate"]
        self._free_state = f["fmi2FreeFMUstate"]

    def do_step(self, t: float, h: float) -> None:
        check("fmi2DoStep", self._do_step(self._component, t, h, fmi2True))

    def get_state(self) -> Any:
        state = fmi2FMUstate()
        check("fmi2GetFMUstate", self._get_state(self._component, ctypes.byref(state)))
        return state

    def set_state(self, state: Any) -> None:
        check("fmi2SetFMUstate", self._set_state(self._component, state))

    def free_state(self, state: Any) -> None:
        check("fmi2FreeFMUstate", self._free_state(self._component, ctypes.byref(state)))
