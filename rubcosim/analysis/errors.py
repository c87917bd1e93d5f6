"""Errors of the analyses: bad input named by its field or flag."""

from __future__ import annotations


class AnalysisError(ValueError):
    """An analysis request that cannot run; the message names the field or flag."""


class MapError(AnalysisError):
    """A system or request the stroboscopic map cannot take."""


class CheckpointError(AnalysisError):
    """A checkpoint directory belongs to another analysis (its settings differ)."""
