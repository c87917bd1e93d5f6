"""Helpers to run FMUs in the plain C FMI host of ``tests/fmi_host`` (not a test module).

The host process contains no Python; it is started with an environment cleaned of everything that
could help it find Python by accident (PYTHONPATH, PYTHONHOME, LD_PRELOAD, LD_LIBRARY_PATH, the
venv's bin directory on PATH), so an FMU must find its interpreter on its own.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import pytest

HOST_SOURCE = Path(__file__).parent / "fmi_host" / "fmi_host.c"

_SCRUBBED = (
    "PYTHONPATH",
    "PYTHONHOME",
    "PYTHONEXECUTABLE",
    "PYTHONSTARTUP",
    "LD_PRELOAD",
    "LD_LIBRARY_PATH",
    "VIRTUAL_ENV",
    "RUBCOSIM_PYTHON",
    "RUBCOSIM_LIBPYTHON",
)


def compile_host(tmpdir: Path) -> Path:
    """Compile the C host into ``tmpdir``; skip the calling test when gcc is unavailable."""
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is not available to compile the C FMI host")
    out = Path(tmpdir) / "fmi_host"
    cmd = [gcc, "-O2", "-Wall", "-Wextra", "-o", str(out), str(HOST_SOURCE), "-ldl"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the C FMI host failed:\n{proc.stderr}")
    return out


_DLOPEN_PROBE = r"""
#include <dlfcn.h>
int main(int argc, char **argv) { return argc > 1 && dlopen(argv[1], RTLD_LAZY) ? 0 : 1; }
"""


def c_can_dlopen(name: str, tmpdir: Path) -> bool:
    """Whether a plain C process (cleaned environment) can dlopen ``name``.

    Asked of a C program because a Python process would also search its own RUNPATH.
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("gcc is not available")
    src = Path(tmpdir) / "dlopen_probe.c"
    exe = Path(tmpdir) / "dlopen_probe"
    src.write_text(_DLOPEN_PROBE)
    subprocess.run([gcc, "-o", str(exe), str(src), "-ldl"], check=True, timeout=120)
    proc = subprocess.run([str(exe), name], env=clean_env(), timeout=60, check=False)
    return proc.returncode == 0


def clean_env(extra_env: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment without any hint of where Python lives, plus ``extra_env``."""
    env = {k: v for k, v in os.environ.items() if k not in _SCRUBBED}
    venv_bin = Path(sys.executable).parent
    if sys.prefix != sys.base_prefix:
        venv_bin = Path(sys.prefix) / "bin"
    drop = {str(venv_bin), str(Path(sys.executable).parent)}
    path = [p for p in env.get("PATH", "").split(os.pathsep) if p and p.rstrip("/") not in drop]
    env["PATH"] = os.pathsep.join(path)
    env.update(extra_env or {})
    return env


def unzip_fmu(fmu_path: Path, dest: Path) -> Path:
    """Extract an FMU into a fresh directory ``dest`` and return it."""
    dest = Path(dest)
    if dest.exists():
        shutil.rmtree(dest)
    with zipfile.ZipFile(fmu_path) as zf:
        zf.extractall(dest)
    return dest


def run_host(
    host: Path,
    fmu_path: Path,
    tmpdir: Path,
    guid: str,
    gets: Iterable[int] = (),
    sets: Mapping[int, float] | None = None,
    steps: int = 10,
    step: float = 0.01,
    *,
    extra_env: Mapping[str, str] | None = None,
    prepare: Callable[[Path], None] | None = None,
    timeout: float = 60.0,
) -> subprocess.CompletedProcess[str]:
    """Unzip ``fmu_path`` under ``tmpdir`` and run it ``steps`` times in the C host.

    ``prepare`` may modify the unzipped FMU before the run (e.g. break its runtime record).
    The model identifier is read from the unzipped modelDescription.xml.
    """
    import xml.etree.ElementTree as ET

    unzipped = unzip_fmu(fmu_path, Path(tmpdir) / f"unzipped_{Path(fmu_path).stem}")
    if prepare is not None:
        prepare(unzipped)
    root = ET.parse(unzipped / "modelDescription.xml").getroot()
    cs = root.find("CoSimulation")
    assert cs is not None
    ident = cs.get("modelIdentifier", "")
    cmd = [str(host), str(unzipped), ident, guid]
    for vr, value in (sets or {}).items():
        cmd += ["--set", f"{vr}={value!r}"]
    for vr in gets:
        cmd += ["--get", str(vr)]
    cmd += ["--steps", str(steps), "--step", repr(step)]
    return subprocess.run(
        cmd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=clean_env(extra_env),
        cwd=tmpdir,
        check=False,
    )
