"""An FMU in a worker process of its own, so that a crash inside it does not end ours.

:class:`IsolatedFmu` has the interface of :class:`.fmu_unit.FmuUnit` (the
master cannot tell them apart) and forwards every call through a pipe to a
spawned process that holds the real ``FmuUnit``.  FMU states stay in the
worker; the master holds their numbers.  When the worker dies (a segmentation
fault or ``abort()`` in the FMU's code) the call raises :class:`FmuCrashError`,
a :class:`.cosim_result.CosimError` naming the FMU, the call and the time:
the master ends the run with status failed and keeps what it recorded up to
the last communication point.  Each call costs a round trip through the pipe
(``benchmarks/bench_isolation.py`` measures it per macro step).
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fmpy import read_model_description

from rubcosim.components.unit import StepError

from .cosim_result import CosimError
from .foreign import signal_names, text_outputs

JOIN_SECONDS = 5.0


class FmuCrashError(CosimError):
    """The worker process of an isolated FMU died; the message names the FMU and the time."""


def _serve(conn: Any, path: str, kwargs: dict[str, Any]) -> None:
    """The worker: build the FMU, then answer ``(method, args)`` requests until ``close``."""
    from .fmu_unit import FmuUnit

    try:
        fmu = FmuUnit(path, **kwargs)
    except Exception as exc:
        conn.send(("error", type(exc).__name__, str(exc)))
        return
    conn.send(("ok", None))
    states: dict[int, Any] = {}
    while True:
        method, args = conn.recv()
        if method == "close":
            fmu.close()
            conn.send(("ok", None))
            return
        try:
            if method == "get_state":
                states[len(states) + 1] = fmu.get_state()
                result: Any = max(states)
            elif method in ("set_state", "serialize_state"):
                result = getattr(fmu, method)(states[args[0]])
            elif method == "free_state":
                result = fmu.free_state(states.pop(args[0]))
            elif method == "deserialize_state":
                states[len(states) + 1] = fmu.deserialize_state(args[0])
                result = max(states)
            else:
                result = getattr(fmu, method)(*args)
        except Exception as exc:
            conn.send(("error", type(exc).__name__, str(exc)))
            continue
        conn.send(("ok", result))


class IsolatedFmu:
    """:class:`.fmu_unit.FmuUnit` in a worker process (same constructor, same methods)."""

    def __init__(self, path: str | Path, **options: Any) -> None:
        """``options``: those of :class:`.fmu_unit.FmuUnit` (``name``, ``params``,
        ``start_time``), passed to it in the worker."""
        self.path = Path(path)
        self.md = read_model_description(str(self.path), validate=False)
        self.name = options.get("name") or self.md.modelName
        self.inputs, self.outputs = signal_names(self.md)
        self.text_outputs = text_outputs(self.md)  # String outputs: read where recorded
        start_time = float(options.get("start_time", 0.0))
        self.time = float(start_time)
        self.messages: list[str] = []
        context = multiprocessing.get_context("spawn")  # no fork of a process with threads
        self._conn, child = context.Pipe()
        kwargs = {**options, "name": self.name}
        self._process = context.Process(
            target=_serve, args=(child, str(self.path), kwargs), daemon=True
        )
        self._process.start()
        child.close()
        self._receive("fmi2Instantiate")

    # --- the pipe -----------------------------------------------------------------
    def _receive(self, what: str) -> Any:
        try:
            reply = self._conn.recv()
        except (EOFError, OSError):
            self._process.join(JOIN_SECONDS)
            raise FmuCrashError(self._death(what)) from None
        if reply[0] == "ok":
            return reply[1]
        kind, message = reply[1], reply[2]
        if kind in ("StepError", "OutputError"):
            raise StepError(message)
        raise CosimError(f"{self.name}: {message}")

    def _death(self, what: str) -> str:
        code = self._process.exitcode
        if code is not None and code < 0:
            how = f"killed by {signal.Signals(-code).name}"
        else:
            how = f"exit code {code}"
        return (
            f"{self.name}: the FMU's worker process died ({how}) in {what} at t = "
            f"{self.time:.9g} s ({self.path.name}, run isolated)"
        )

    def _call(self, method: str, *args: Any) -> Any:
        try:
            self._conn.send((method, args))
        except (BrokenPipeError, OSError):
            raise FmuCrashError(self._death(method)) from None
        return self._receive(method)

    # --- the FmuUnit interface -------------------------------------------------------
    def set_values(self, values: Mapping[str, Any]) -> None:
        self._call("set_values", dict(values))

    def get_values(self, names: list[str]) -> dict[str, Any]:
        return self._call("get_values", list(names))

    def set_input(self, name: str, value: float) -> None:
        self._call("set_input", name, value)

    def set_input_polynomial(self, name: str, value: float, d1: float, d2: float) -> None:
        self._call("set_input_polynomial", name, value, d1, d2)

    def set_input_polynomials(self, rows: Mapping[str, tuple[float, float, float]]) -> None:
        self._call("set_input_polynomials", dict(rows))

    def set_inputs(self, values: Mapping[str, float]) -> None:
        self._call("set_inputs", dict(values))

    def get_outputs(self) -> dict[str, Any]:
        return self._call("get_outputs")

    def do_step(self, t: float, h: float) -> None:
        self.time = t
        self._call("do_step", t, h)
        self.time = t + h

    def get_state(self) -> int:
        return self._call("get_state")

    def set_state(self, state: int) -> None:
        self._call("set_state", state)

    def free_state(self, state: int) -> None:
        self._call("free_state", state)

    def serialize_state(self, state: int) -> bytes:
        return self._call("serialize_state", state)

    def deserialize_state(self, data: bytes) -> int:
        return self._call("deserialize_state", data)

    def close(self) -> None:
        """Close the FMU and end the worker; a dead worker is only reaped."""
        if self._process.is_alive():
            try:
                self._conn.send(("close", ()))
                self._conn.recv()
            except (EOFError, OSError):
                pass
        self._process.join(JOIN_SECONDS)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._conn.close()

    def __enter__(self) -> IsolatedFmu:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
