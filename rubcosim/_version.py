"""The release of rubcosim, in a module of its own: what the package re-exports as
``rubcosim.__version__``, and what the modules below the package (the FMU builder) read
without importing the package, which imports the API above them."""

from __future__ import annotations

__version__ = "0.1.0"
