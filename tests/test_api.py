"""The Python API (``import rubcosim as rc``), Scenario.with_params, the bundled
scenarios (also in a built wheel) and the README's example."""

import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import rubcosim as rc
from rubcosim.analysis import sweep
from rubcosim.analysis.maps import DEFAULT_RTOL, StroboscopicMap
from rubcosim.analysis.sweep import SECTION_PER_PERIOD, parse_param
from rubcosim.cli import main
from rubcosim.scenario import ScenarioError, build_scenario, load_scenario

REPO = Path(__file__).resolve().parents[1]
DUFFING = REPO / "scenarios" / "impact_duffing.toml"
OSC_SHORT = {"sim.t_end": 5.0}


def readme_example() -> str:
    """The fenced python block of the README's "Python API" section."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Python API") :]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_import_is_cheap_and_lazy():
    heavy = ("matplotlib", "dask", "rubcosim.orchestrator", "rubcosim.api", "rubcosim.scenario")
    code = (
        f"import sys, rubcosim as rc; heavy = {heavy!r};"
        "print(sorted(m for m in sys.modules if m.startswith(heavy)));"
        "print(callable(rc.load), 'load' in dir(rc))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == ["[]", "True True"]


def test_readme_example_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    exec(compile(readme_example(), "README.md", "exec"), {"__name__": "readme"})
    out = capsys.readouterr().out
    assert "jeffcott_rigid_stator" in out and out.count("\n") >= 8
    header = (tmp_path / "flagship.csv").read_text().splitlines()[0]
    assert header.startswith("time,rotor.x,rotor.y")


def test_sweep_keeps_the_overrides_the_scenario_was_loaded_with():
    # the bug: the sweep rebuilt every value from the file and integrated restitution 0.8
    sc = load_scenario(DUFFING, ["oscillator.restitution=0.3"])
    param = parse_param("oscillator.forcing_amplitude=1.0:1.1:2")
    res = sweep.sweep(sc, param, periods=4, discard=20, workers=1)
    assert res.impacts["up"][0].sum() > 0  # it impacts: the restitution matters

    def first_value(restitution: str) -> np.ndarray:
        system = load_scenario(
            DUFFING, [f"oscillator.restitution={restitution}", "oscillator.forcing_amplitude=1.0"]
        ).system
        orbit = StroboscopicMap(system, DEFAULT_RTOL).orbit(
            sc.system.y0, skip=20, keep=4, mode=sc.system.mode0, max_section=SECTION_PER_PERIOD * 4
        )
        return orbit.points

    assert np.array_equal(res.points["up"][0], first_value("0.3"))
    assert not np.allclose(res.points["up"][0], first_value("0.8"))
    # the systems of every value keep it, and a scenario built in memory sweeps too
    systems = sweep.sweep_systems(sc, param, param.values)
    assert [s.units["oscillator"].params["restitution"] for s in systems] == [0.3, 0.3]
    memory = build_scenario(sc.data, params={"oscillator.restitution": 0.3})
    again = sweep.sweep(memory, param, periods=4, discard=20, workers=1)
    assert np.array_equal(again.points["up"], res.points["up"])


def test_with_params_keeps_every_override_and_validates():
    sc = rc.load(DUFFING, set={"oscillator.restitution": 0.3, "sim.t_end": 10.0})
    wider = sc.with_params({"oscillator.barrier": np.float64(1.5)})
    assert wider is not sc and sc.system.units["oscillator"].params["barrier"] == 1.0
    params = wider.system.units["oscillator"].params
    assert params["restitution"] == 0.3 and params["barrier"] == 1.5
    assert wider.sim["t_end"] == 10.0
    assert wider.overrides == {
        "oscillator.restitution": 0.3,
        "sim.t_end": 10.0,
        "oscillator.barrier": 1.5,
    }
    # a later setting of the same key wins, as with --set twice
    assert wider.with_params({"oscillator.restitution": 0.5}).parameters[
        "oscillator.restitution"
    ] == pytest.approx(0.5)
    with pytest.raises(ScenarioError, match="restitution"):
        sc.with_params({"oscillator.restitution": 1.5})
    # --set strings and a dict give the same scenario
    strings = rc.load(DUFFING, set=["oscillator.restitution=0.3", "sim.t_end=10.0"])
    assert strings.overrides == sc.overrides and strings.parameters == sc.parameters


def test_bad_keys_raise_errors_naming_them():
    with pytest.raises(ScenarioError, match="rotor.nope"):
        rc.load("jeffcott_rigid_stator", set={"rotor.nope": 1})
    with pytest.raises(ScenarioError, match="oscillator"):
        rc.load("jeffcott_rigid_stator", set={"oscillator.x0": 1})
    with pytest.raises(ScenarioError, match="nodot"):
        rc.load("jeffcott_rigid_stator", set={"nodot": 1})
    sc = rc.load("impact_duffing")
    with pytest.raises(ScenarioError, match="rotor.nope"):
        rc.sweep(sc, "rotor.nope", [1.0, 2.0])
    with pytest.raises(ScenarioError, match="oscillator.nope"):
        rc.sweep(sc, "oscillator.nope", [1.0, 2.0])
    with pytest.raises(ScenarioError, match="no such scenario file"):
        rc.load("no_such_bundled_scenario")
    with pytest.raises(ScenarioError, match="engine"):
        rc.simulate(sc, engine="rk4")
    with pytest.raises(ScenarioError, match="backend"):
        rc.cosimulate(sc, backend="tcp")


def test_in_memory_scenario_and_result_object(tmp_path):
    data = load_scenario("impact_oscillator_linear").data
    sc = rc.load(data, set=OSC_SHORT)
    assert sc.source == "" and sc.name == "impact_oscillator_linear"
    res = rc.simulate(sc, engine="fast")
    assert res.ok and res.status == "ok", res.message
    assert res.t[0] == 0.0 and res.t[-1] == pytest.approx(5.0)
    assert res["oscillator.x"].shape == res.t.shape and "oscillator.x" in res.names
    with pytest.raises(KeyError, match="oscillator.x"):
        res["rotor.x"]
    impacts = res.events.times("impact")
    assert impacts.size == res.counters["impacts"] > 0 and np.all(np.diff(impacts) > 0)
    assert res.report()["n_impacts"] == impacts.size


def test_to_csv_is_the_csv_of_rubcosim_run(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "impact_oscillator_linear", "--set", "sim.t_end=5.0", "--out", str(out)]
    assert main(argv) == 0  # a bundled scenario by name
    res = rc.simulate("impact_oscillator_linear", set=OSC_SHORT)  # FMPy-like: name + values
    res.to_csv(tmp_path / "api.csv")
    assert (tmp_path / "api.csv").read_bytes() == (out / "results.csv").read_bytes()
    co = rc.cosimulate(rc.load("impact_oscillator_linear", set=OSC_SHORT), backend="direct")
    co.to_csv(tmp_path / "co.csv")
    argv = [*argv[:-1], str(tmp_path / "corun"), "--backend", "direct"]
    assert main(argv) == 0
    assert (tmp_path / "co.csv").read_bytes() == (tmp_path / "corun/results.csv").read_bytes()
    assert co.ok and co.engine == "cosim-direct" and co.t.size == res.t.size


def test_cli_lists_the_bundled_scenarios(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = [line.split()[0] for line in lines]
    assert names == sorted(p.stem for p in (REPO / "scenarios").glob("*.toml"))
    assert list(rc.scenarios()) == names
    flagship = lines[names.index("jeffcott_rigid_stator")]
    assert "Jeffcott rotor, centred rigid stator" in flagship


def test_the_rubcosim_executable_runs_console_main_and_returns_its_exit_code(tmp_path):
    """The installed ``rubcosim`` script is :func:`console_main`; bad input still exits 2."""
    script = Path(sys.executable).with_name("rubcosim").read_text()
    assert "from rubcosim.cli import console_main" in script
    ok = subprocess.run([sys.executable, "-m", "rubcosim.cli", "scenarios"], capture_output=True)
    assert ok.returncode == 0 and b"impact_duffing" in ok.stdout
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "rubcosim.cli",
            "run",
            "impact_duffing",
            "--out",
            "out",
            "--set",
            "oscillator.restitution=1.5",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert bad.returncode == 2 and "oscillator.restitution" in bad.stderr


def test_the_executable_stops_quietly_when_its_reader_goes_away():
    # `rubcosim ... | head -1` on a long output: the pipe closes after the first line
    child = (
        "import sys, rubcosim.cli as cli\n"
        "def noisy(argv=None):\n"
        "    for i in range(200000):\n"
        "        print('line', i)\n"
        "    return 0\n"
        "cli.main = noisy\n"
        "sys.exit(cli.console_main())\n"
    )
    p = subprocess.Popen(
        [sys.executable, "-c", child], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert p.stdout.readline() == b"line 0\n"
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait() == 1 and err == ""


def test_the_wheel_ships_the_scenarios(tmp_path):
    # built from a copy of the sources: setuptools leaves build/ beside pyproject.toml
    src = tmp_path / "src"
    skip = shutil.ignore_patterns("__pycache__", "*.egg-info", "build")
    for name in ("rubcosim", "components", "fmus", "orchestrator", "scenarios"):
        shutil.copytree(REPO / name, src / name, ignore=skip)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, src / name)
    wheels = tmp_path / "wheels"
    pip = [sys.executable, "-m", "pip"]
    subprocess.run(
        [*pip, "wheel", "--no-deps", "-q", "-w", str(wheels), str(src)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    (wheel,) = wheels.glob("rubcosim-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    shipped = sorted(Path(n).name for n in names if n.startswith("rubcosim/scenario_files/"))
    assert shipped == sorted(p.name for p in (REPO / "scenarios").glob("*.toml"))
    # installed on its own, the package finds them by name, away from the repository
    target = tmp_path / "site"
    subprocess.run(
        [*pip, "install", "--no-deps", "-q", "--target", str(target), str(wheel)],
        check=True,
        capture_output=True,
    )
    code = (
        "import rubcosim, rubcosim.cli as cli; from rubcosim.scenario import load_scenario;"
        "print(rubcosim.__file__); print(load_scenario('jeffcott_rigid_stator').source);"
        "cli.main(['scenarios'])"
    )
    env = {"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env
    )
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith(str(target)) and lines[1].startswith(str(target))
    assert lines[1].endswith("scenario_files/jeffcott_rigid_stator.toml")
    assert any(line.startswith("impact_duffing ") for line in lines[2:])
