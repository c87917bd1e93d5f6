"""Make pythonfmu-built FMUs loadable by plain C FMI hosts.

pythonfmu 0.7 puts its ``libpythonfmu-export.so`` into every FMU as ``binaries/linux64/<id>.so``.
That library does not link libpython (it relies on the host process having Python loaded) and,
when it must start Python itself, does so with the program name ``./PythonFMU``: the interpreter
then finds neither the virtual environment nor its site-packages (numpy), and the library calls
``Py_Finalize`` when unloaded, which can crash at process exit.  FMI tools without Python inside
therefore cannot run these FMUs.

:func:`install_loader` rewrites such an FMU so that ``binaries/linux64/<id>.so`` is a small C shim
(``loader/rubcosim_fmu_loader.c``) that starts the right Python on demand and forwards every FMI
call to the original library, stored as ``<id>_pythonfmu_export.so``.  The Python runtime used to
build the FMU is recorded in ``resources/rubcosim_python.txt`` so the shim can find libpython and
the venv on the same machine without any environment variables.  The shim also provides
``fmi2SetRealInputDerivatives``, which pythonfmu lacks: it sets the tunable parameters that carry
each input's derivatives, listed in ``resources/rubcosim_input_derivatives.txt``.
"""

from __future__ import annotations

import os
import re
import shutil
import stat
import subprocess
import sys
import sysconfig
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

__all__ = [
    "DERIVATIVES_FILE",
    "VARIABLES_FILE",
    "DERIVATIVE_CARRIER",
    "EXPORT_SUFFIX",
    "LOADER_FILES",
    "LOADER_SOURCE",
    "RUNTIME_FILE",
    "compile_loader",
    "derivative_table",
    "variable_table",
    "install_loader",
    "model_identifier",
    "python_runtime",
]

#: C source of the loader shim (its FMI 2.0 entry points), shipped next to this module.
LOADER_SOURCE = Path(__file__).parent / "loader" / "rubcosim_fmu_loader.c"
#: Every file the shim is compiled from: its C sources and their shared header.
LOADER_FILES = (*sorted(LOADER_SOURCE.parent.glob("*.c")), LOADER_SOURCE.with_name("rcs_shim.h"))
#: Archive name of the runtime record read by the shim.
RUNTIME_FILE = "resources/rubcosim_python.txt"
#: Archive name of the input-derivative table read by the shim.
DERIVATIVES_FILE = "resources/rubcosim_input_derivatives.txt"
# every variable's value reference, FMI type and name: the shim refuses a wrongly typed
# fmi2Get/Set call with fmi2Error (pythonfmu would answer fmi2Fatal and drop the instance)
VARIABLES_FILE = "resources/rubcosim_variables.txt"
_TYPE_LETTERS = {"Real": "R", "Integer": "I", "Enumeration": "I", "Boolean": "B", "String": "S"}
#: Names of the tunable parameters that carry a real input's first and second derivative.
DERIVATIVE_CARRIER = "{input}_d{order}"
#: Suffix appended to the model identifier for the original pythonfmu export library.
EXPORT_SUFFIX = "_pythonfmu_export"

_PLATFORM_DIR = "binaries/linux64"
# Fixed timestamp for entries written here, so rebuilding gives the same archive metadata.
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def _loaded_libpython() -> str:
    """Path of the libpython mapped into this process, read from ``/proc/self/maps``.

    Used when sysconfig's LIBDIR is stale (relocated builds such as python-build-standalone).
    """
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return ""
    for line in maps.splitlines():
        fields = line.split(maxsplit=5)
        path = fields[5] if len(fields) == 6 else ""
        if re.search(r"/libpython3[.\d]*\.so(\.[\d.]+)?$", path):
            return path
    return ""


def python_runtime() -> dict[str, str]:
    """Describe the running interpreter for the FMU loader shim.

    Returns ``executable`` (``sys.executable`` unresolved, so a venv's ``bin/python`` is kept and
    its ``pyvenv.cfg`` is honoured), ``libpython`` (full path of the shared library, empty when the
    interpreter has none), ``soname`` and ``version`` (``"X.Y"``).
    """
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    names = [str(sysconfig.get_config_var(key) or "") for key in ("INSTSONAME", "LDLIBRARY")]
    shared = [n for n in names if n.endswith(".so") or ".so." in n]
    soname = shared[0] if shared else ""

    libpython = ""
    for name in shared:
        candidate = Path(libdir) / name
        if libdir and candidate.is_file():
            libpython = str(candidate)
            break
    if not libpython:
        libpython = _loaded_libpython()
        if libpython and not soname:
            soname = Path(libpython).name
    return {
        "executable": sys.executable or "",
        "libpython": libpython,
        "soname": soname,
        "version": version,
    }


def _runtime_text(runtime: dict[str, str]) -> str:
    lines = [
        "# Python runtime recorded by rubcosim when this FMU was built; read by the loader shim",
        "# binaries/linux64/<id>.so. Override with RUBCOSIM_PYTHON / RUBCOSIM_LIBPYTHON.",
    ]
    lines += [f"{key}={runtime.get(key, '')}" for key in ("executable", "libpython", "soname")]
    lines.append(f"version={runtime.get('version', '')}")
    return "\n".join(lines) + "\n"


def compile_loader(dest: Path, model_identifier: str) -> Path:
    """Compile the loader shim into ``dest/<model_identifier>.so`` and return its path.

    The shim is compiled on the building machine because it must match that machine's glibc; it
    needs only libdl/libpthread, not Python headers.
    """
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError(
            "gcc was not found on PATH; it is required to compile the rubcosim FMU loader shim "
            f"({LOADER_SOURCE}). Install gcc (e.g. 'apt-get install gcc') and retry."
        )
    missing = [str(path) for path in (LOADER_SOURCE, *LOADER_FILES) if not path.is_file()]
    if missing:
        raise RuntimeError(f"FMU loader source is missing: {', '.join(missing)}")
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    out = dest / f"{model_identifier}.so"
    cmd = [
        gcc,
        "-shared",
        "-fPIC",
        "-O2",
        "-fvisibility=hidden",
        "-Wall",
        "-o",
        str(out),
        *(str(path) for path in LOADER_FILES if path.suffix == ".c"),
        "-ldl",
        "-lpthread",
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise RuntimeError(f"gcc could not compile the FMU loader shim: {exc}") from exc
    if proc.returncode != 0:
        raise RuntimeError(
            f"gcc failed ({proc.returncode}) compiling the FMU loader shim:\n"
            f"{' '.join(cmd)}\n{proc.stderr.strip()}"
        )
    return out


def model_identifier(fmu: Path) -> str:
    """Co-simulation model identifier of an FMU (``CoSimulation/@modelIdentifier``)."""
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    cs = root.find("CoSimulation")
    if cs is None or not cs.get("modelIdentifier"):
        raise ValueError(f"{fmu}: modelDescription.xml has no CoSimulation/@modelIdentifier")
    return cs.get("modelIdentifier", "")


def derivative_table(model_description: bytes) -> str:
    """``input_vr order carrier_vr`` lines for every real input whose derivative carriers
    (:data:`DERIVATIVE_CARRIER`) the model declares: the shim's fmi2SetRealInputDerivatives."""
    root = ET.fromstring(model_description)
    reals = {}
    for sv in root.iter("ScalarVariable"):
        if sv.find("Real") is not None:
            reals[sv.get("name")] = (sv.get("causality"), int(sv.get("valueReference", "0")))
    lines = []
    for name, (causality, vr) in reals.items():
        if causality != "input":
            continue
        for order in (1, 2):
            carrier = reals.get(DERIVATIVE_CARRIER.format(input=name, order=order))
            if carrier is not None:
                lines.append(f"{vr} {order} {carrier[1]}\n")
    return "".join(lines)


def variable_table(model_description: bytes) -> str:
    """``vr type name`` lines, one per scalar variable (type ``R``, ``I``, ``B`` or ``S``;
    an Enumeration is accessed as an Integer): the shim's type check."""
    root = ET.fromstring(model_description)
    lines = []
    for sv in root.iter("ScalarVariable"):
        letter = next((_TYPE_LETTERS[t.tag] for t in sv if t.tag in _TYPE_LETTERS), None)
        if letter is not None:
            lines.append(f"{int(sv.get('valueReference', '0'))} {letter} {sv.get('name')}\n")
    return "".join(lines)


def install_loader(fmu: Path) -> None:
    """Install the loader shim into a pythonfmu-built FMU, in place.

    ``binaries/linux64/<id>.so`` becomes ``<id>_pythonfmu_export.so``, the compiled shim takes its
    name and ``resources/rubcosim_python.txt`` records the current interpreter.  Other platforms'
    binaries are left alone.  Running it again refreshes shim and record and keeps the export
    library.  The archive is rewritten normalised (sorted entries, fixed timestamps and modes, no
    bytecode), so the same inputs give the same bytes; it is written to a temporary file and
    swapped in with ``os.replace``, so a failure leaves the original FMU intact.
    """
    fmu = Path(fmu)
    ident = model_identifier(fmu)
    shim_name = f"{_PLATFORM_DIR}/{ident}.so"
    export_name = f"{_PLATFORM_DIR}/{ident}{EXPORT_SUFFIX}.so"

    with tempfile.TemporaryDirectory(prefix="rubcosim_loader_") as tmp:
        shim = compile_loader(Path(tmp), ident)
        with zipfile.ZipFile(fmu) as src:
            names = set(src.namelist())
            if export_name in names:
                export_info = src.getinfo(export_name)  # already installed: keep the original
            elif shim_name in names:
                export_info = src.getinfo(shim_name)
            else:
                raise ValueError(f"{fmu}: no {shim_name} (not a pythonfmu FMU for linux64?)")
            entries: dict[str, tuple[zipfile.ZipInfo, bytes]] = {}
            for info in src.infolist():
                ours = (shim_name, export_name, RUNTIME_FILE, DERIVATIVES_FILE, VARIABLES_FILE)
                skip = info.filename in ours
                if skip or info.is_dir() or "__pycache__" in info.filename:
                    continue
                mode = 0o755 if info.filename.startswith("binaries/") else 0o644
                entries[info.filename] = (_new_info(info.filename, mode), src.read(info))
            export_bytes = src.read(export_info)
            description = src.read("modelDescription.xml")
            table, variables = derivative_table(description), variable_table(description)

        entries[export_name] = (_new_info(export_name, 0o755), export_bytes)
        entries[shim_name] = (_new_info(shim_name, 0o755), shim.read_bytes())
        entries[RUNTIME_FILE] = (
            _new_info(RUNTIME_FILE, 0o644),
            _runtime_text(python_runtime()).encode(),
        )
        entries[DERIVATIVES_FILE] = (_new_info(DERIVATIVES_FILE, 0o644), table.encode())
        entries[VARIABLES_FILE] = (_new_info(VARIABLES_FILE, 0o644), variables.encode())

        fd, tmp_fmu = tempfile.mkstemp(suffix=".fmu", prefix=f".{fmu.stem}.", dir=fmu.parent)
        os.close(fd)
        try:
            os.chmod(tmp_fmu, stat.S_IMODE(fmu.stat().st_mode))  # mkstemp made it 0600
            with zipfile.ZipFile(tmp_fmu, "w", compression=zipfile.ZIP_DEFLATED) as dst:
                for name in sorted(entries):
                    info, data = entries[name]
                    dst.writestr(info, data, compress_type=zipfile.ZIP_DEFLATED)
            os.replace(tmp_fmu, fmu)
        except BaseException:
            Path(tmp_fmu).unlink(missing_ok=True)
            raise


def _new_info(name: str, mode: int) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=_ZIP_EPOCH)
    info.external_attr = (0o100000 | mode) << 16  # regular file with unix permissions
    info.compress_type = zipfile.ZIP_DEFLATED
    return info
