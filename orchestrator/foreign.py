"""Foreign FMUs: FMI 2.0 co-simulation FMUs not built by rubcosim, as units of a scenario.

A scenario names them in ``[fmus.NAME]`` tables::

    [fmus.ball]
    path = "bouncing_ball.fmu"   # relative to the scenario file
    start = { e = 0.8 }          # start values set before initialisation (optional)
    record = ["h", "v"]          # outputs to record (optional; default: every output)
    isolate = true               # in a worker process: a crash fails the run (optional)

The master steps them like any unit, through fmpy, whatever the backend of
the rubcosim units (so ``--backend direct`` mixes in-process units and FMUs).
Their inputs and outputs can be wired in ``[connections]``.  Whether an
output depends on the inputs at the same instant is read from the model
structure (outputs with no dependencies listed are assumed to depend on all
inputs, as FMI 2.0 says).  The monolithic engines cannot simulate a foreign
FMU, so such a scenario runs only as a co-simulation.

Variables of every FMI 2.0 type are handled: Real, Integer, Boolean and
Enumeration outputs are numbers, recorded and connected like any signal (an
Integer, Boolean or Enumeration input takes only a source of its own type,
never a Real one).  A String output is recorded where ``record`` (or
``[outputs] record``) names it, as text (its own quoted column of
``results.csv``, a text array in the result); by default only the numeric
outputs are.  String variables can be given start values, and are never
connected: a connection from or to one is refused with a message naming it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

KEYS = ("path", "start", "record", "isolate")
# FMI types read as numbers; a String variable is recorded as text, never connected
NUMERIC_TYPES = ("Real", "Integer", "Boolean", "Enumeration")


def signal_names(md: Any) -> tuple[list[str], list[str]]:
    """The inputs and the numeric outputs of a model description (what the master reads)."""
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    outputs = [
        v.name for v in md.modelVariables if v.causality == "output" and v.type in NUMERIC_TYPES
    ]
    return inputs, outputs


def text_outputs(md: Any) -> list[str]:
    """The String outputs of a model description (recorded as text where asked)."""
    return [v.name for v in md.modelVariables if v.causality == "output" and v.type == "String"]


class ForeignFmuError(ValueError):
    """A ``[fmus.NAME]`` table or the FMU it names is unusable; the message names the key."""


@dataclass(frozen=True)
class ForeignFmu:
    """A foreign FMU as a scenario declares it, checked against its model description."""

    name: str
    path: Path
    start: dict[str, Any] = field(default_factory=dict)
    record: tuple[str, ...] = ()
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    feedthrough: bool = True
    can_get_set_state: bool = False
    can_interpolate: bool = False
    isolate: bool = False  # run it in a worker process (a crash fails the run, not the process)
    types: dict[str, str] = field(default_factory=dict)  # FMI type of each input and output
    strings: tuple[str, ...] = ()  # String inputs and outputs: never connected
    texts: tuple[str, ...] = ()  # String outputs: recorded as text where asked

    def refused(self) -> dict[str, str]:
        """Why each String variable cannot be connected (for the wiring's messages)."""
        return {name: STRING_REFUSED for name in self.strings}


STRING_REFUSED = (
    "a String variable; only Real, Integer, Boolean and Enumeration signals are connected"
)


def foreign_fmu(name: str, table: Mapping[str, Any], base_dir: Path) -> ForeignFmu:
    """Validate ``[fmus.<name>]``; a relative ``path`` is taken from ``base_dir``."""
    from fmpy import read_model_description

    where = f"fmus.{name}"
    unknown = sorted(set(table) - set(KEYS))
    if unknown:
        raise ForeignFmuError(f"{where}.{unknown[0]} is not a key (known: {', '.join(KEYS)})")
    raw = table.get("path")
    if not isinstance(raw, str) or not raw:
        raise ForeignFmuError(f"{where}.path is required: the FMU file")
    path = Path(raw) if Path(raw).is_absolute() else base_dir / raw
    if not path.is_file():
        raise ForeignFmuError(f"{where}.path: {path} is not a file")
    try:
        md = read_model_description(str(path))
    except Exception as exc:
        raise ForeignFmuError(f"{where}.path: {path} is not a readable FMU ({exc})") from None
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise ForeignFmuError(
            f"{where}.path: {path.name} is not an FMI 2.0 co-simulation FMU "
            f"(fmiVersion {md.fmiVersion}, co-simulation: {md.coSimulation is not None})"
        )
    variables = {v.name: v for v in md.modelVariables}
    signals = [v for v in md.modelVariables if v.causality in ("input", "output")]
    strings = tuple(v.name for v in signals if v.type not in NUMERIC_TYPES)
    inputs = tuple(v.name for v in signals if v.causality == "input" and v.type in NUMERIC_TYPES)
    outputs = tuple(v.name for v in signals if v.causality == "output" and v.type in NUMERIC_TYPES)
    start = table.get("start", {})
    if not isinstance(start, Mapping):
        raise ForeignFmuError(f"{where}.start must be a table of start values")
    for key in start:
        var = variables.get(key)
        if var is None or var.causality not in ("parameter", "input"):
            raise ForeignFmuError(f"{where}.start.{key}: not a parameter or input of {path.name}")
    isolate = table.get("isolate", False)
    if not isinstance(isolate, bool):
        raise ForeignFmuError(f"{where}.isolate = {isolate!r} must be true or false")
    record = table.get("record", list(outputs))
    if not isinstance(record, list) or not all(isinstance(r, str) for r in record):
        raise ForeignFmuError(f"{where}.record must be a list of output names")
    texts = tuple(text_outputs(md))
    for r in record:
        if r not in outputs and r not in texts:
            raise ForeignFmuError(
                f"{where}.record: {r!r} is not an output of {path.name} "
                f"(outputs: {', '.join((*outputs, *texts))})"
            )
    return ForeignFmu(
        name=name,
        path=path,
        start=dict(start),
        record=tuple(record),
        inputs=inputs,
        outputs=outputs,
        feedthrough=_feedthrough(md, inputs),
        can_get_set_state=bool(md.coSimulation.canGetAndSetFMUstate),
        can_interpolate=bool(md.coSimulation.canInterpolateInputs),
        isolate=isolate,
        types={v.name: v.type for v in signals},
        strings=strings,
        texts=texts,
    )


def _feedthrough(md: Any, inputs: tuple[str, ...]) -> bool:
    if not inputs:
        return False
    for unknown in md.outputs:
        deps = unknown.dependencies
        if deps is None or any(d.causality == "input" for d in deps):
            return True
    return False
