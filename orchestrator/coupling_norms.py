"""The coupling error of a macro step: what each unit was given for the step's end
against what its sources gave there, relative to the signal's scale and ``cosim.rtol``.

A mixin of :class:`.master.Master` (it reads the master's scales and settings).
"""

from __future__ import annotations

from collections.abc import Mapping


class CouplingNorms:
    """Error norms of a step for a master (see :mod:`.master`)."""

    def _error(self, given: Mapping[str, float], real: Mapping[str, float], tol: float) -> float:
        err = 0.0
        for key, r in real.items():
            g = given[key]
            scale = max(self.scale[key], abs(r), abs(g))
            if g != r:
                err = max(err, abs(g - r) / (tol * scale))
        return err

    def _worst(self, given: Mapping[str, float], real: Mapping[str, float]) -> str:
        """The input whose coupling error is the largest relative to its scale."""
        return max(
            real,
            key=lambda k: abs(given[k] - real[k]) / max(self.scale[k], abs(real[k]), 1e-300),
            default="no input",
        )

    def _deviation(self, key: str, given: Mapping[str, float], real: Mapping[str, float]):
        """Signed error of one input in tolerances: its sources' value minus the value
        its unit was given, over ``rtol`` times its scale."""
        g, r = given[key], real[key]
        scale = max(self.scale[key], abs(r), abs(g))
        return (r - g) / (self.settings.rtol * scale) if scale > 0.0 else 0.0
