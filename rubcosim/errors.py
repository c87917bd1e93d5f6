"""The error of bad scenario input (a file, an override, an API argument)."""

from __future__ import annotations


class ScenarioError(ValueError):
    """The scenario file or an override is malformed; the message names the key."""
