"""pythonfmu FMUs with the rubcosim loader shim run in a plain C host and still in Python hosts.

A probe slave importing numpy is built with pythonfmu, fitted with the loader
(:func:`rubcosim.fmus.native.install_loader`) and run by ``tests/fmi_host/fmi_host.c``, a C
process that has no Python and no environment pointing to one.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

pythonfmu_builder = pytest.importorskip("pythonfmu.builder")
from rubcosim.fmus.native import (  # noqa: E402
    EXPORT_SUFFIX,
    RUNTIME_FILE,
    install_loader,
    model_identifier,
)

from fmi_c_host import c_can_dlopen, compile_host, run_host  # noqa: E402

if not sys.platform.startswith("linux"):
    pytest.skip("the FMU loader shim is Linux-only", allow_module_level=True)

K, U, STEPS, H = 2.5, 0.3, 100, 0.01

PROBE = textwrap.dedent(
    '''
    import sys

    import numpy as np
    from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real


    class RubcosimProbe(Fmi2Slave):
        """y = sin(u) * k + t computed with numpy; in_venv tells whether a venv is active."""

        author = "rubcosim tests"

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.k = 1.0
            self.u = 0.0
            self.y = 0.0
            self.in_venv = 0.0
            self.register_variable(
                Real("k", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable)
            )
            self.register_variable(Real("u", causality=Fmi2Causality.input))
            self.register_variable(
                Real("y", causality=Fmi2Causality.output, initial=Fmi2Initial.exact)
            )
            self.register_variable(
                Real("in_venv", causality=Fmi2Causality.output, initial=Fmi2Initial.exact)
            )

        def do_step(self, current_time, step_size):
            t = current_time + step_size
            self.y = float(np.sin(np.float64(self.u)) * self.k + t)
            self.in_venv = float(sys.prefix != sys.base_prefix)
            return True
    '''
)


def _variables(fmu: Path) -> tuple[str, dict[str, int]]:
    with zipfile.ZipFile(fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    refs = {
        v.get("name", ""): int(v.get("valueReference", "-1")) for v in root.iter("ScalarVariable")
    }
    return root.get("guid", ""), refs


@pytest.fixture(scope="module")
def probe_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The probe FMU with the loader installed (built once per module)."""
    src = tmp_path_factory.mktemp("probe_src")
    script = src / "rubcosim_probe_slave.py"
    script.write_text(PROBE)
    out = tmp_path_factory.mktemp("probe_fmu")
    saved_path = list(sys.path)
    try:
        fmu = pythonfmu_builder.FmuBuilder.build_FMU(
            script, dest=out, canGetAndSetFMUstate=True, canSerializeFMUstate=True
        )
    finally:
        sys.path[:] = saved_path  # the builder prepends the script's directory
        sys.modules.pop("rubcosim_probe_slave", None)
    install_loader(Path(fmu))
    return Path(fmu)


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return compile_host(tmp_path_factory.mktemp("host"))


def _run(host: Path, fmu: Path, tmp_path: Path, **kwargs) -> subprocess.CompletedProcess[str]:
    guid, refs = _variables(fmu)
    return run_host(
        host,
        fmu,
        tmp_path,
        guid,
        gets=[refs["y"], refs["in_venv"]],
        sets={refs["k"]: K, refs["u"]: U},
        steps=STEPS,
        step=H,
        **kwargs,
    )


def _assert_clean(proc: subprocess.CompletedProcess[str]) -> None:
    msg = f"exit {proc.returncode}\nstdout:\n{proc.stdout[-2000:]}\nstderr:\n{proc.stderr[-4000:]}"
    assert proc.returncode == 0, msg
    for marker in ("Fatal", "Segmentation", "Traceback", "core dumped"):
        assert marker not in proc.stderr, msg


def _assert_values(stdout: str) -> None:
    rows = [[float(x) for x in line.split(",")] for line in stdout.strip().splitlines()]
    assert len(rows) == STEPS
    expected_venv = float(sys.prefix != sys.base_prefix)
    for i, (t, y, in_venv) in enumerate(rows):
        assert t == pytest.approx((i + 1) * H, abs=1e-12)
        assert y == pytest.approx(math.sin(U) * K + t, abs=1e-12)
        assert in_venv == expected_venv  # the interpreter found the same environment as ours


def _break_runtime_record(unzipped: Path) -> None:
    """Point every entry of the recorded runtime at something that does not exist."""
    (unzipped / RUNTIME_FILE).write_text(
        "executable=/nonexistent/rubcosim/bin/python\n"
        "libpython=/nonexistent/rubcosim/lib/libpython0.0.so.1.0\n"
        "soname=libpython0.0-rubcosim-missing.so.1.0\n"
        "version=0.0\n"
    )


def test_fmu_layout(probe_fmu: Path, tmp_path: Path) -> None:
    ident = model_identifier(probe_fmu)
    with zipfile.ZipFile(probe_fmu) as zf:
        names = zf.namelist()
        runtime = dict(
            line.split("=", 1)
            for line in zf.read(RUNTIME_FILE).decode().splitlines()
            if "=" in line and not line.startswith("#")
        )
        export = zf.read(f"binaries/linux64/{ident}{EXPORT_SUFFIX}.so")
    assert names == sorted(names)
    assert f"binaries/linux64/{ident}.so" in names
    assert any(n.startswith("binaries/win64/") for n in names)  # other platforms untouched
    assert set(runtime) == {"executable", "libpython", "soname", "version"}
    assert runtime["executable"] == sys.executable
    assert Path(runtime["libpython"]).is_file()

    # Re-installing refreshes the shim but keeps the original pythonfmu library.
    again = tmp_path / probe_fmu.name
    shutil.copy2(probe_fmu, again)
    install_loader(again)
    with zipfile.ZipFile(again) as zf:
        assert zf.namelist() == names
        assert zf.read(f"binaries/linux64/{ident}{EXPORT_SUFFIX}.so") == export


def test_c_host_runs_numpy_slave(host: Path, probe_fmu: Path, tmp_path: Path) -> None:
    proc = _run(host, probe_fmu, tmp_path)
    _assert_clean(proc)
    _assert_values(proc.stdout)


def test_c_host_uses_environment_overrides(host: Path, probe_fmu: Path, tmp_path: Path) -> None:
    """With the recorded runtime unusable, RUBCOSIM_LIBPYTHON / RUBCOSIM_PYTHON are enough."""
    runtime_lib = _recorded(probe_fmu)["libpython"]
    proc = _run(
        host,
        probe_fmu,
        tmp_path,
        prepare=_break_runtime_record,
        extra_env={"RUBCOSIM_LIBPYTHON": runtime_lib, "RUBCOSIM_PYTHON": sys.executable},
    )
    _assert_clean(proc)
    _assert_values(proc.stdout)


def _recorded(fmu: Path) -> dict[str, str]:
    with zipfile.ZipFile(fmu) as zf:
        text = zf.read(RUNTIME_FILE).decode()
    return dict(line.split("=", 1) for line in text.splitlines() if "=" in line and line[0] != "#")


def test_c_host_reports_missing_python(host: Path, probe_fmu: Path, tmp_path: Path) -> None:
    """Every libpython candidate fails: fmi2Instantiate logs what was tried and returns NULL."""
    if c_can_dlopen("libpython3.so", tmp_path):
        pytest.skip("libpython3.so is installed system-wide, so the last fallback would succeed")
    missing = tmp_path / "no-such-libpython.so"
    proc = _run(
        host,
        probe_fmu,
        tmp_path,
        prepare=_break_runtime_record,
        extra_env={"RUBCOSIM_LIBPYTHON": str(missing)},
    )
    assert proc.returncode == 4, proc.stderr  # the host's "fmi2Instantiate returned NULL"
    assert proc.stdout == ""
    err = proc.stderr
    assert "[Error]" in err
    assert f"RUBCOSIM_LIBPYTHON={missing}" in err
    assert "/nonexistent/rubcosim/lib/libpython0.0.so.1.0" in err  # recorded path was tried
    assert "libpython0.0-rubcosim-missing.so.1.0" in err  # recorded soname was tried
    assert "libpython3.so" in err  # generic fallback was tried
    assert "RUBCOSIM_PYTHON" in err  # and the user is told what to set
    assert "Fatal" not in err and "Segmentation" not in err


def test_fmpy_in_process(probe_fmu: Path) -> None:
    """In a Python host (Python already running) the shim must leave Python alone."""
    code = textwrap.dedent(
        f"""
        import json
        from fmpy import simulate_fmu
        r = simulate_fmu({str(probe_fmu)!r}, start_values={{"k": {K!r}, "u": {U!r}}},
                         stop_time=1.0, output_interval={H!r}, output=["y", "in_venv"])
        print(json.dumps({{"t": r["time"].tolist(), "y": r["y"].tolist(),
                          "in_venv": r["in_venv"].tolist()}}))
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["t"][-1] == pytest.approx(1.0)
    for t, y in list(zip(result["t"], result["y"], strict=True))[1:]:
        assert y == pytest.approx(math.sin(U) * K + t, abs=1e-12)
    assert result["in_venv"][-1] == float(sys.prefix != sys.base_prefix)


def test_fmpy_validate(probe_fmu: Path) -> None:
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(probe_fmu)) == []


def test_c_host_says_which_python_replaces_a_missing_recorded_one(
    host: Path, probe_fmu: Path, tmp_path: Path
) -> None:
    """The build's interpreter is gone (its venv renamed): the FMU still runs, on another
    Python, and says so at fmi2Warning with the reason, instead of switching silently."""
    recorded = _recorded(probe_fmu)

    def break_executable(unzipped: Path) -> None:
        (unzipped / RUNTIME_FILE).write_text(
            f"executable=/nonexistent/rubcosim/bin/python\nlibpython={recorded['libpython']}\n"
            f"soname={recorded['soname']}\nversion={recorded['version']}\n"
        )

    proc = _run(host, probe_fmu, tmp_path, prepare=break_executable,
                extra_env={"RUBCOSIM_PYTHON": sys.executable})  # fmt: skip
    _assert_clean(proc)
    _assert_values(proc.stdout)
    proc = _run(host, probe_fmu, tmp_path, prepare=break_executable)
    assert "[Warning]" in proc.stderr, proc.stderr
    assert "recorded executable /nonexistent/rubcosim/bin/python: not an executable" in proc.stderr


def test_c_host_names_a_module_the_chosen_python_lacks(
    host: Path, probe_fmu: Path, tmp_path: Path
) -> None:
    system_python = Path("/usr/bin/python3.11")
    recorded = _recorded(probe_fmu)
    probe = subprocess.run([str(system_python), "-c", "import numpy"], capture_output=True)
    if not system_python.is_file() or probe.returncode == 0:
        pytest.skip("needs a Python 3.11 without numpy at /usr/bin/python3.11")
    proc = _run(host, probe_fmu, tmp_path, prepare=_break_runtime_record,
                extra_env={"RUBCOSIM_LIBPYTHON": recorded["libpython"],
                           "RUBCOSIM_PYTHON": str(system_python)})  # fmt: skip
    assert proc.returncode == 4, proc.stderr  # fmi2Instantiate returned NULL
    assert "cannot import numpy" in proc.stderr
    assert "RUBCOSIM_PYTHON" in proc.stderr and "RUBCOSIM_LIBPYTHON" in proc.stderr
    assert "Traceback" not in proc.stderr and "Segmentation" not in proc.stderr
