"""Variable access for :mod:`.fmi_slave`: every variable's getter and setter by FMI type and
value reference, looked up once, and why a get or set is refused.

Bundled into every FMU with the slave; imports nothing from ``rubcosim``.
"""

from __future__ import annotations

import math
from typing import Any

from pythonfmu import Boolean, Fmi2Variability, Integer, Real, String

# what a refused getter hands pythonfmu (which reads one value per reference regardless)
PLACEHOLDER: dict[type, Any] = {Real: math.nan, Integer: 0, Boolean: False, String: ""}
CONVERT: dict[type, Any] = {Real: float, Integer: int, Boolean: bool, String: str}


class Access:
    """Every variable's getter and setter by type and value reference; the setters twice:
    before fmi2ExitInitializationMode, and after it (without the fixed parameters)."""

    def __init__(self, variables: dict[int, Any]) -> None:
        self.variables = variables
        self.getters: dict[type, dict[int, Any]] = {k: {} for k in PLACEHOLDER}
        self.setters: dict[type, tuple[dict[int, Any], dict[int, Any]]] = {
            k: ({}, {}) for k in PLACEHOLDER
        }
        for vr, var in variables.items():
            kind = type(var)
            if var.getter is not None:
                self.getters[kind][vr] = var.getter
            if var.setter is not None:
                self.setters[kind][0][vr] = var.setter
                if var.variability != Fmi2Variability.fixed:
                    self.setters[kind][1][vr] = var.setter

    def why(self, kind: type, vrs: list[int], setting: bool, stepping: bool) -> str:
        """Why a get or set of ``vrs`` as ``kind`` is refused ("" if nothing is wrong)."""
        call = f"fmi2{'Set' if setting else 'Get'}{kind.__name__}"
        for vr in vrs:
            var = self.variables.get(vr)
            if var is None:
                return f"{call}: no variable has value reference {vr}"
            if not isinstance(var, kind):
                return f"{call}: {var.name} is of type {type(var).__name__}, not {kind.__name__}"
            if setting and var.setter is None:
                return f"{call}: {var.name} is an {var.causality.name}; it cannot be set"
            if setting and stepping and var.variability == Fmi2Variability.fixed:
                return (
                    f"{call}: {var.name} is a fixed parameter; it cannot change after "
                    "fmi2ExitInitializationMode (fmi2Reset, then set it)"
                )
        return ""


def reason(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def per_second(unit: str, order: int) -> str:
    """The unit of the ``order``-th time derivative: N -> N/s, N/s2; m/s -> m/s2, m/s3."""
    if not unit:
        return ""
    if unit.endswith("/s"):
        return f"{unit}{order + 1}"
    return f"{unit}/s" if order == 1 else f"{unit}/s{order}"
