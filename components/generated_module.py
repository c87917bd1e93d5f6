"""Modules generated from the registry: written once under numba's cache directory and
imported from there.

numba caches a compiled function only if it takes no function argument, so a
dispatch over the registered unit types (their hybrid kernels, their contact laws)
is written out as source, one branch per type, and imported as a module of its own:
numba then caches what calls it like any other function.  The file is named by the
hash of its text, so a change of the registry or of a kernel's module makes a new
one and an unchanged one is written once.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType


def _write(text: str, path: Path, what: str) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # write then rename: a process reading it never sees half a module
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as exc:
        raise OSError(
            f"cannot write the generated {what} module {path} ({exc.strerror}); "
            "set NUMBA_CACHE_DIR to a writable directory"
        ) from exc


def load_generated(text: str, stem: str, package: str, what: str) -> ModuleType:
    """The module whose source is ``text``: written as ``generated/{stem}_{hash}.py``
    under ``NUMBA_CACHE_DIR`` (or the temporary directory) if not there yet, and
    imported once per process as ``{package}_{stem}_{hash}`` (``package`` keeps a
    bundled copy of this package apart from the installed one); ``what`` names it
    in an error."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    base = os.environ.get("NUMBA_CACHE_DIR") or tempfile.gettempdir()
    path = Path(base) / "generated" / f"{stem}_{digest}.py"
    if not path.is_file() or path.read_text() != text:
        _write(text, path, what)
    name = f"{package.replace('.', '_')}_{stem}_{digest}"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
