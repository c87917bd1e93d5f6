"""An FMI 2.0 co-simulation FMU behind the same small interface as a rubcosim Unit.

Loaded with fmpy; works for the FMUs built here and for any other FMI 2.0
co-simulation FMU.  Names, not value references, are used everywhere;
failures raise with the messages the FMU logged.
"""

from __future__ import annotations

import contextlib
import shutil
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2Integer,
    free,
)

from rubcosim.components.unit import StepError

from .fmi_direct import StepCalls, ValueCall
from .foreign import signal_names, text_outputs

# A pythonfmu FMU imports `pythonfmu` from its own resources unless the package is already
# loaded, and that copy has no build binaries: load the installed one first, so that building
# FMUs later in this process (the fmu backend builds missing ones) still works.
with contextlib.suppress(ImportError):
    import pythonfmu.builder  # noqa: F401

FMI2_FATAL = 4


class FmuError(RuntimeError):
    """An FMU could not be loaded, initialised or called; the message names it."""


class FmuUnit:
    """One instance of an FMU.

    ``params`` and ``inputs`` (by variable name) are set before initialisation;
    ``start_time`` is passed to fmi2SetupExperiment.
    """

    def __init__(
        self,
        path: str | Path,
        name: str | None = None,
        params: Mapping[str, Any] | None = None,
        start_time: float = 0.0,
    ) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FmuError(f"FMU not found: {self.path}")
        try:
            self.md = read_model_description(str(self.path), validate=False)
        except Exception as exc:
            raise FmuError(f"{self.path} is not a readable FMU: {exc}") from exc
        if self.md.coSimulation is None:
            raise FmuError(f"{self.path} has no co-simulation interface")
        self.name = name or self.md.modelName
        self.variables = {v.name: v for v in self.md.modelVariables}
        # what the master reads after every step: the numeric outputs (a String output is
        # read only where recorded, and never connected: see orchestrator.foreign)
        self.inputs, self.outputs = signal_names(self.md)
        self.text_outputs = text_outputs(self.md)  # String outputs: read where recorded
        self.messages: list[str] = []
        # per list of names read together: (names of one type, function giving their values)
        self._groups: dict[tuple[str, ...], list[tuple[list[str], Any]]] = {}
        # the per-step calls on all-real variables, straight to the C functions (fmi_direct)
        self._real_calls: dict[tuple[str, tuple[str, ...]], ValueCall | None] = {}
        self._steps: StepCalls | None = None
        # FMI calls made by the value, step and state methods (the parameters' included)
        self.fmi_calls = 0
        self._lock = threading.Lock()
        self._dir = extract(str(self.path))
        self._callbacks = self._make_callbacks()
        self._fmu = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self._dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=self.name,
        )
        self._instantiated = False
        self._fatal = False
        try:
            self._call(
                "fmi2Instantiate", self._fmu.instantiate, callbacks=self._callbacks, loggingOn=True
            )
            self._instantiated = True
            self._steps = StepCalls(self._fmu)
            self._call("set parameters", self.set_values, dict(params or {}))
            self._call("fmi2SetupExperiment", self._fmu.setupExperiment, startTime=start_time)
            self._call("fmi2EnterInitializationMode", self._fmu.enterInitializationMode)
            self._call("fmi2ExitInitializationMode", self._fmu.exitInitializationMode)
        except Exception:
            self.close()
            raise
        self.time = float(start_time)

    # --- values ------------------------------------------------------------------
    def _variable(self, name: str) -> Any:
        try:
            return self.variables[name]
        except KeyError:
            raise FmuError(f"{self.name}.{name} is not a variable of {self.path.name}") from None

    def _real_call(
        self, function: str, names: tuple[str, ...], orders: tuple[int, ...] = ()
    ) -> ValueCall | None:
        """The direct call of ``function`` on ``names`` (each repeated per order when
        ``orders`` are given), made once; None unless they are all real variables."""
        key = (function, names)
        if key not in self._real_calls:
            found = [self._variable(name) for name in names]
            call = None
            if all(v.type == "Real" for v in found):
                refs = [v.valueReference for v in found for _ in (orders or (0,))]
                call = ValueCall(self._fmu, function, refs, orders * len(names))
            self._real_calls[key] = call
        return self._real_calls[key]

    def set_values(self, values: Mapping[str, Any]) -> None:
        """Set ``values`` by name: one FMI call per type (the order within a type is the
        mapping's)."""
        call = self._real_call("fmi2SetReal", tuple(values)) if self._instantiated else None
        if call is not None:
            self.fmi_calls += 1
            call.set([float(v) for v in values.values()])
            return
        groups: dict[str, tuple[list[int], list[Any]]] = {}
        for name, value in values.items():
            var = self._variable(name)
            kind = "Integer" if var.type == "Enumeration" else var.type
            refs, vals = groups.setdefault(kind, ([], []))
            refs.append(var.valueReference)
            vals.append(value)
        self.fmi_calls += len(groups)
        for kind, (refs, vals) in groups.items():
            if kind == "Real":
                self._fmu.setReal(refs, [float(v) for v in vals])
            elif kind == "Integer":
                self._fmu.setInteger(refs, [round(v) for v in vals])
            elif kind == "Boolean":
                self._fmu.setBoolean(refs, [bool(v) for v in vals])
            else:
                self._fmu.setString(refs, [str(v) for v in vals])

    def get_values(self, names: list[str]) -> dict[str, Any]:
        """The values of ``names``: one FMI call per type, value references resolved once."""
        groups = self._groups.get(tuple(names))
        if groups is None:
            by_kind: dict[str, tuple[list[str], list[int]]] = {}
            for name in names:
                var = self._variable(name)
                kind = "Integer" if var.type == "Enumeration" else var.type
                by_kind.setdefault(kind, ([], []))
                by_kind[kind][0].append(name)
                by_kind[kind][1].append(var.valueReference)
            groups = [(group, self._getter(kind, refs)) for kind, (group, refs) in by_kind.items()]
            self._groups[tuple(names)] = groups
        out: dict[str, Any] = {}
        self.fmi_calls += len(groups)
        for group, get in groups:
            out.update(zip(group, get(), strict=True))
        return out

    def _getter(self, kind: str, refs: list[int]) -> Any:
        """A function giving the values of ``refs`` of one type: reals and integers
        straight from the C functions (fmi_direct), the rest through fmpy."""
        if kind == "Real":
            return ValueCall(self._fmu, "fmi2GetReal", refs).get
        if kind == "Integer":
            return ValueCall(self._fmu, "fmi2GetInteger", refs, ctype=fmi2Integer).get
        if kind == "Boolean":
            return lambda: self._fmu.getBoolean(refs)
        return lambda: [_text(v) for v in self._fmu.getString(refs)]

    def set_input(self, name: str, value: float) -> None:
        self._call(f"set {name}", self.set_values, {name: value})

    def set_input_polynomial(self, name: str, value: float, d1: float, d2: float) -> None:
        """The input's value and first two time derivatives for the next step
        (fmi2SetReal, then fmi2SetRealInputDerivatives; needs canInterpolateInputs)."""
        var = self._variable(name)
        vr = var.valueReference
        self._call(f"set {name}", self.set_values, {name: value})
        if var.type != "Real":  # a discrete input has no derivatives: its value holds
            if d1 or d2:
                raise FmuError(
                    f"fmi2SetRealInputDerivatives {name}: {self.name}.{name} is an {var.type} "
                    "input; it has no derivatives"
                )
            return
        self._call(
            f"fmi2SetRealInputDerivatives {name}",
            self._fmu.setRealInputDerivatives,
            [vr, vr],
            [1, 2],
            [d1, d2],
        )

    def set_input_polynomials(self, rows: Mapping[str, tuple[float, float, float]]) -> None:
        """:meth:`set_input_polynomial` for several inputs ``{name: (value, d1, d2)}`` in
        one fmi2SetReal and one fmi2SetRealInputDerivatives."""
        real: list[str] = []
        derivs: list[float] = []
        for name, (_, d1, d2) in rows.items():
            var = self._variable(name)
            if var.type != "Real":
                if d1 or d2:
                    raise FmuError(
                        f"fmi2SetRealInputDerivatives {name}: {self.name}.{name} is an "
                        f"{var.type} input; it has no derivatives"
                    )
                continue
            real.append(name)
            derivs += [d1, d2]
        self._call("set inputs", self.set_values, {k: r[0] for k, r in rows.items()})
        if real:
            call = self._real_call("fmi2SetRealInputDerivatives", tuple(real), (1, 2))
            self.fmi_calls += 1
            self._call(f"fmi2SetRealInputDerivatives {', '.join(real)}", call.set, derivs)

    def set_inputs(self, values: Mapping[str, float]) -> None:
        self._call("set inputs", self.set_values, values)

    def get_outputs(self) -> dict[str, Any]:
        """Every output; an FMU that cannot give them fails like a step (StepError)."""
        try:
            return self._call("get outputs", self.get_values, self.outputs)
        except FmuError as exc:
            raise StepError(f"{exc} at t = {self.time:.9g} s") from exc

    # --- stepping and state --------------------------------------------------------
    def do_step(self, t: float, h: float) -> None:
        """fmi2DoStep; a discarded or failed step raises StepError with the FMU's messages."""
        self.messages.clear()
        self.fmi_calls += 1
        try:
            self._steps.do_step(t, h)
        except Exception as exc:
            if getattr(exc, "status", None) == FMI2_FATAL:
                self._fatal = True
            detail = "; ".join(self.messages) or str(exc)
            raise StepError(f"{self.name}: step from t = {t} to {t + h} failed: {detail}") from exc
        self.time = t + h

    def get_state(self) -> Any:
        """An FMU state handle (free it with :meth:`free_state` when done)."""
        self.fmi_calls += 1
        return self._call("fmi2GetFMUstate", self._steps.get_state)

    def set_state(self, state: Any) -> None:
        self.fmi_calls += 1
        self._call("fmi2SetFMUstate", self._steps.set_state, state)

    def free_state(self, state: Any) -> None:
        self.fmi_calls += 1
        self._call("fmi2FreeFMUstate", self._steps.free_state, state)

    def serialize_state(self, state: Any) -> bytes:
        return bytes(self._call("fmi2SerializeFMUstate", self._fmu.serializeFMUState, state))

    def deserialize_state(self, data: bytes) -> Any:
        return self._call("fmi2DeSerializeFMUstate", self._fmu.deserializeFMUState, data)

    def close(self) -> None:
        """Terminate and free the instance; remove the extracted files.

        After an ``fmi2Fatal`` the standard allows no further call to the instance (and
        pythonfmu 0.7 would release its Python objects a second time): it is dropped.
        """
        if self._instantiated and not self._fatal:
            with contextlib.suppress(Exception):  # freeing must go on after a failed terminate
                self._fmu.terminate()
            self._fmu.freeInstance()
        self._instantiated = False
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> FmuUnit:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- plumbing ---------------------------------------------------------------------
    def _call(self, what: str, function: Any, *args: Any, **kwargs: Any) -> Any:
        self.messages.clear()
        try:
            return function(*args, **kwargs)
        except FmuError:
            raise
        except Exception as exc:
            if getattr(exc, "status", None) == FMI2_FATAL:
                self._fatal = True
            detail = "; ".join(self.messages) or str(exc)
            raise FmuError(f"{self.name}: {what} failed: {detail}") from exc

    def _make_callbacks(self) -> fmi2CallbackFunctions:
        def log(env: Any, instance: bytes, status: int, category: bytes, message: bytes) -> None:
            text = message.decode("utf-8", "replace") if message else ""
            with self._lock:
                self.messages.append(text)

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        return callbacks


def _text(value: bytes | str | None) -> str:
    """A String variable's value as text (fmpy gives the C string's bytes; NULL is "")."""
    if value is None:
        return ""
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value
