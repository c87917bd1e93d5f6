"""Hybrid units: a unit type that is a whole nonsmooth model, written once as kernels.

A hybrid unit type declares its physics as four compiled kernels over its
own state ``y``, its discrete mode and its parameter array ``p`` (packed by
``pack`` in the order it chooses):

* ``rhs(t, y, mode, p, dy)``: the vector field in ``mode``;
* ``events(t, y, mode, p, g, dirs, rates)``: event functions in up to
  :data:`.hybrid_dispatch.N_EVENTS` slots (the caller fills every slot with ``g = 1``,
  ``dirs = 0``, ``rates = -1`` first); ``dirs[k]`` -1 falling, +1 rising, 2
  either; ``rates[k]`` the slot holding g_k's time derivative, or -1;
* ``apply(k, t, y, mode, p)``: the event map of slot ``k`` (changes ``y`` in
  place), returning ``(new mode, event kind)`` (:data:`.hybrid_dispatch.KIND_NAMES`);
* ``outputs(t, y, mode, p, out)``: the outputs named by ``outputs``.

Inputs (``inputs``, real signals of the unit class) reach the kernels through
the end of ``p``: from slot ``input_base`` on, the step's start time, then
value, first and second derivative of each input (:func:`input_value` reads
them).  :class:`HybridUnit` writes them before every step; the reference,
where the unit is the whole model, leaves them at zero.

The monolithic reference compiles these kernels into its engines
(:mod:`.hybrid_dispatch`); :class:`HybridUnit` steps the
same kernels as a co-simulation unit (and so as an FMU).  The physics of such
a unit type is therefore written exactly once.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .flat_hybrid import hybrid_outputs, row_output_args
from .flat_rows import MAX_OUTPUTS
from .flat_units import unit_row
from .hybrid_dispatch import hybrid_types
from .jit import njit
from .kernels import polynomial_at
from .stepping import step_hybrid
from .unit import Unit


@dataclass(frozen=True)
class HybridKernels:
    """The compiled physics of a hybrid unit type (see the module's docstring).

    ``outputs`` names what the ``outputs`` kernel writes, in order; ``pack(params)``
    gives the parameter array ``p`` (up to ``input_base``); ``initial(params)`` the
    initial state and mode; ``inputs`` the inputs the kernels read.
    """

    rhs: Callable[..., None]
    events: Callable[..., None]
    apply: Callable[..., tuple[int, int]]
    output: Callable[..., None]
    outputs: tuple[str, ...]
    pack: Callable[[Mapping[str, Any]], np.ndarray]
    initial: Callable[[Mapping[str, Any]], tuple[np.ndarray, int]]
    inputs: tuple[str, ...] = ()
    input_base: int = 0

    def parameters(self, params: Mapping[str, Any]) -> np.ndarray:
        """``pack(params)`` with the input slots after it, zero."""
        packed = self.pack(params)
        p = np.zeros(self.input_base + 1 + 3 * len(self.inputs))
        p[: packed.size] = packed
        return p


@njit(inline="always")
def input_value(p: np.ndarray, base: int, i: int, t: float) -> float:
    """Input ``i`` of a hybrid unit at time ``t`` (s): the polynomial over the current
    step stored from ``p[base]`` on (step start, then value, d1, d2 per input)."""
    j = base + 1 + 3 * i
    return polynomial_at(p[j], p[j + 1], p[j + 2], t - p[base])


class HybridUnit(Unit):
    """A co-simulation unit stepping a hybrid unit type's kernels.

    Inside a communication step the kernels' events are located and their map
    applied (:func:`.stepping.advance`), so every impact and every change of
    mode happens at its own time, whatever the step.  Subclasses set
    ``kernels`` and the usual unit declarations.
    """

    kernels: ClassVar[HybridKernels]
    feedthrough = False
    _index = -1  # the type's index among the hybrid types (of the stepper's dispatch)
    _row_outputs: tuple | None = None

    def _initial_state(self) -> dict[str, Any]:
        y0, mode0 = self.kernels.initial(self.params)
        self._index = [t.hybrid for t in hybrid_types()].index(self.kernels)
        self._p = self.kernels.parameters(self.params)
        self._row_outputs = None  # what _outputs passes the row kernel, from the parameters
        return {"y": np.array(y0, dtype=float), "h": 0.0, "mode": int(mode0), "impacts": 0}

    def _set_input_slots(self, t: float) -> None:
        base = self.kernels.input_base
        self._p[base] = t
        for i, name in enumerate(self.kernels.inputs):
            d1, d2 = self.du.get(name, (0.0, 0.0))
            self._p[base + 1 + 3 * i : base + 4 + 3 * i] = (self.u[name], d1, d2)

    def _advance(self, t: float, h: float) -> None:
        q, st = self.params, self.state
        self._set_input_slots(t)
        st["y"], st["mode"], impacts, st["h"] = step_hybrid(
            self._index, t, t + h, st["y"], st["mode"], st["h"], self._p, q["rtol"], q["atol"]
        )
        st["impacts"] += impacts

    # outputs that are a function of the mode alone: name -> value in mode 0, 1, ...
    mode_outputs: ClassVar[Mapping[str, tuple[int, ...]]] = {}

    def _outputs(self) -> dict[str, float]:
        # the compiled master's kernel on this unit's row (flat_hybrid.hybrid_outputs):
        # which output comes from where is decided there, once, for both masters
        if self._row_outputs is None:
            self._row_outputs = row_output_args(self)
        out = np.zeros(MAX_OUTPUTS)
        n_y, idx, code, by_mode, p = self._row_outputs
        n_out = len(self.outputs)
        hybrid_outputs(n_y, idx.size, n_out, idx, code, by_mode, p, unit_row(self), out)
        return {
            s.name: (int(v) if s.kind == "integer" else float(v))
            for s, v in zip(self.outputs, out[:n_out], strict=True)
        }
