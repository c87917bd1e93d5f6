"""Stroboscopic maps, classification, Floquet multipliers, sweeps and cell mapping,
each checked against an answer known independently of the code under test."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from rubcosim.analysis import cellmap, sweep
from rubcosim.analysis.cellmap import LABEL_BOUNDARY, Grid, cell_mapping
from rubcosim.analysis.errors import CheckpointError, MapError
from rubcosim.analysis.floquet import FLOQUET_RTOL, floquet
from rubcosim.analysis.maps import StroboscopicMap, admissible
from rubcosim.analysis.motion import NOT_PERIODIC, classify, distinct_count
from rubcosim.analysis.parallel import Checkpoint, InlineExecutor, run_tasks
from rubcosim.analysis.sweep import ParamRange, parse_param
from rubcosim.cli import main
from rubcosim.scenario import ScenarioError, load_scenario

SCENARIOS = Path(__file__).resolve().parent.parent / "scenarios"
DUFFING = SCENARIOS / "impact_duffing.toml"
# x'' + 0.1 x' + x + x^3 = 2 cos(2 t), no barrier: two period-1 attractors coexist
# (found by direct simulation from a grid of initial states, see the tests below)
TWO_WELL = ['oscillator.stop="none"', "oscillator.forcing_amplitude=2.0"]
SMALL, LARGE = np.array([-0.7881, 0.1294]), np.array([2.243, 1.4116])


def duffing_map(overrides=(), rtol=1e-9):
    return StroboscopicMap(load_scenario(DUFFING, list(overrides)).system, rtol=rtol)


def test_classify_labels_period_and_impacts():
    scale = np.array([1.0, 1.0])
    two = np.array([[0.1, 0.2], [0.3, -0.1]] * 5)
    motion = classify(two, np.array([1, 0] * 5), scale)
    assert (motion.period, motion.impacts, motion.label, motion.periodic) == (2, 1, "2-1", True)
    rng = np.random.default_rng(1)
    chaos = classify(rng.random((40, 2)), np.ones(40, dtype=int), scale)
    assert chaos.label == NOT_PERIODIC and chaos.distinct == 40 and not chaos.periodic
    assert distinct_count(np.array([[0.0, 0.0], [0.0, 5e-7], [1.0, 0.0]]), scale) == 2
    with pytest.raises(ValueError, match="points must be"):
        classify(np.zeros((1, 2)), np.zeros(1), scale)
    with pytest.raises(ValueError, match="not finite"):
        classify(np.full((4, 2), np.nan), np.zeros(4), scale)


def test_duffing_orbits_reach_the_two_attractors_the_scenario_documents():
    smap = duffing_map()
    big = smap.orbit(skip=100, keep=10)
    small = smap.orbit(np.zeros(2), skip=300, keep=10)
    assert big.ok and classify(big.points, big.impacts, smap.scale).label == "1-1"
    assert classify(small.points, small.impacts, smap.scale, tol=1e-5).label == "1-0"
    # the batch kernel maps a state exactly as the orbit does
    images, modes, impacts, status = smap.map(np.vstack([big.points[0], small.points[0]]))
    assert np.array_equal(status, [0, 0]) and np.array_equal(impacts, [1, 0])
    assert np.allclose(images, [big.points[1], small.points[1]], rtol=0, atol=1e-12)
    assert np.array_equal(modes, [0, 0]) and np.array_equal(big.modes, np.zeros(10))


def test_impact_section_of_the_duffing_1_1_orbit():
    # the impacting orbit hits the barrier x = 1 once a period, always at one phase,
    # leaving it with a negative speed (the same as a plain run of the engine logs)
    from rubcosim.reference.simulate import simulate

    smap = duffing_map(rtol=1e-11)
    orbit = smap.orbit(skip=100, keep=6)
    phases, after = orbit.impact_phases, orbit.impact_states
    assert phases.size == 6 and np.ptp(phases) < 1e-8 and 0.0 <= phases[0] < 2 * math.pi
    assert np.allclose(after[:, 0], 1.0, atol=1e-12) and np.all(after[:, 1] < 0.0)
    sc = load_scenario(DUFFING)
    t_hit = 100 * smap.period + phases[0] / (2 * math.pi) * smap.period
    before = simulate(sc.system, t_hit, t_start=0.0, rtol=1e-11, t_eval=np.array([t_hit]))
    logged = before.events.state[before.events.of_kind("impact")[-1]]  # a separate run
    assert logged[1] == pytest.approx(after[0, 1], rel=1e-6)
    assert smap.orbit(skip=100, keep=6, max_section=2).impact_phases.size == 2


def test_map_refuses_what_it_cannot_take():
    with pytest.raises(MapError, match="units.controller"):
        StroboscopicMap(load_scenario(SCENARIOS / "jeffcott_delayed_feedback.toml").system)
    with pytest.raises(MapError, match="rtol"):
        duffing_map(rtol=2.0)
    smap = duffing_map()
    with pytest.raises(MapError, match="y0 has shape"):
        smap.orbit(np.zeros(3))
    with pytest.raises(MapError, match="keep"):
        smap.orbit(keep=0)
    with pytest.raises(MapError, match="columns"):
        smap.map(np.zeros((2, 3)))
    # beyond the rigid barrier at x = 1 is not a state of the system
    assert admissible(smap, np.array([[0.5, 0.0], [1.5, 0.0]])).tolist() == [True, False]


def test_floquet_product_is_restitution_squared_times_damping_decay():
    # Liouville: the flow contracts areas by exp(-b T); each impact's saltation matrix
    # has determinant r^2.  The 1-1 orbit's multipliers multiply to r^2 exp(-b T).
    smap = duffing_map(rtol=FLOQUET_RTOL)
    start = smap.orbit(skip=100, keep=1).final_state
    f = floquet(smap, start, 1)
    assert f.impacts == 1 and f.residual < 1e-10 and f.stable
    assert np.prod(f.multipliers).real == pytest.approx(0.8**2 * math.exp(-0.1 * math.pi), 1e-7)


def test_floquet_of_a_linear_oscillator_matches_its_closed_form():
    # x'' + b x' + x = cos(2 t), barrier out of reach: multipliers exp((-b/2 +- i wd) T)
    smap = StroboscopicMap(
        load_scenario(
            SCENARIOS / "impact_duffing.toml",
            ["oscillator.cubic_stiffness=0.0", 'oscillator.stop="none"'],
        ).system,
        rtol=FLOQUET_RTOL,
    )
    f = floquet(smap, np.zeros(2), 1)
    T, b = math.pi, 0.1
    expected = np.exp(complex(-b / 2, math.sqrt(1 - b * b / 4)) * T)
    assert f.impacts == 0 and f.kind == "neimark-sacker"
    found = sorted(f.multipliers, key=lambda z: z.imag)
    assert np.allclose(found, [expected.conjugate(), expected], atol=1e-7)


def test_floquet_stops_when_newton_leaves_its_box():
    # the linear oscillator's fixed point (closed form: the forced response at t = 0,
    # x = -3 / (9 + 0.04) ~ -0.33) from a start far from it: Newton's first step lands on
    # it (the map is affine), outside a box that excludes it, inside one that holds it
    smap = StroboscopicMap(
        load_scenario(DUFFING, ["oscillator.cubic_stiffness=0.0", 'oscillator.stop="none"']).system,
        rtol=FLOQUET_RTOL,
    )
    start = np.array([0.5, 0.5])
    with pytest.raises(MapError, match="left the box"):
        floquet(smap, start, 1, box=(np.array([0.0, 0.0]), np.array([1.0, 1.0])))
    f = floquet(smap, start, 1, box=(np.array([-1.0, -1.0]), np.array([1.0, 1.0])))
    assert f.state[0] == pytest.approx(-3.0 / 9.04, abs=1e-9)


def test_floquet_refuses_a_grazing_orbit():
    # a free orbit that just touches the barrier: perturbations change its impacts
    smap = duffing_map(["oscillator.cubic_stiffness=0.0"], rtol=FLOQUET_RTOL)
    free = StroboscopicMap(
        load_scenario(DUFFING, ["oscillator.cubic_stiffness=0.0", 'oscillator.stop="none"']).system,
        rtol=FLOQUET_RTOL,
    )
    fixed = floquet(free, np.zeros(2), 1).state
    # amplitude of x'' + 0.1 x' + x = cos(2t): 1/sqrt(9 + 0.04); barrier at that amplitude
    amp = 1.0 / math.sqrt(9.0 + 0.04)
    grazing = StroboscopicMap(
        load_scenario(
            DUFFING, ["oscillator.cubic_stiffness=0.0", f"oscillator.barrier={amp!r}"]
        ).system,
        rtol=FLOQUET_RTOL,
    )
    with pytest.raises(MapError, match="grazing"):
        floquet(grazing, fixed, 1, max_iter=0)
    assert smap.n_state == 2


def test_cell_mapping_of_a_linear_impact_oscillator_finds_one_attractor():
    smap = StroboscopicMap(load_scenario(SCENARIOS / "impact_oscillator_linear.toml").system, 1e-7)
    grid = Grid(24, 24, -7.0, 0.0, -7.0, 7.0)  # up to the barrier at x = 0
    basins = cell_mapping(smap, grid, samples=4, seed=3, workers=1)
    counts = basins.counts()
    assert basins.n_attractors == 1 and counts["boundary"] == 0
    assert counts["basins"][0] + counts["escape"] == grid.n_cells
    assert basins.motions[0]["points_in_group"] == 1.0
    # the 1-1 orbit found by simulating the scenario, independently of the cells
    lin = smap.orbit(skip=200, keep=4)
    assert basins.motions[0]["label"] == "1-1"
    assert np.allclose(basins.motions[0]["poincare_points"][0], lin.final_state, atol=1e-6)


def test_cell_mapping_finds_the_two_coexisting_duffing_attractors():
    smap = duffing_map(TWO_WELL, rtol=1e-7)
    # a region of moderate energy: from far out the hardening spring throws points
    # out of any region in one period (escape cells); there both basins show at 30x30
    grid = Grid(30, 30, -2.0, 4.0, -4.0, 4.0)
    basins = cell_mapping(smap, grid, samples=4, seed=0, workers=2)
    assert basins.n_attractors == 2
    found = sorted((m["poincare_points"][0] for m in basins.motions), key=lambda p: p[0])
    assert np.allclose(found[0], SMALL, atol=1e-3) and np.allclose(found[1], LARGE, atol=1e-3)
    assert all(m["label"] == "1-0" for m in basins.motions)
    counts = basins.counts()
    assert min(counts["basins"]) > 10 and counts["escape"] > 0
    # each attractor's own cells lie in its basin; boundary cells reach both
    for k in range(2):
        assert np.all(basins.labels[basins.attractor_of == k] == k)
    assert np.all(basins.reach[basins.labels == LABEL_BOUNDARY].sum(axis=1) >= 2)
    # the same samples through a Dask cluster give the same graph
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster:
        remote = cell_mapping(smap, grid, 4, 0, scheduler=cluster.scheduler_address)
    assert np.array_equal(remote.image, basins.image)


def test_cell_mapping_resumes_from_its_checkpoint(tmp_path, monkeypatch):
    smap = duffing_map(TWO_WELL, rtol=1e-6)
    grid = Grid(12, 12, -4.0, 4.0, -6.0, 6.0)
    ckpt = tmp_path / "ck"
    first = cell_mapping(smap, grid, 2, 0, workers=1, checkpoint_dir=ckpt, chunk=40)
    done = sorted(ckpt.glob("cells_*.npz"))
    assert len(done) == 4
    done[-1].unlink()  # as if interrupted before the last task finished
    calls = []
    real = cellmap.map_cells
    monkeypatch.setattr(cellmap, "map_cells", lambda *a: calls.append(a[2]) or real(*a))
    again = cell_mapping(smap, grid, 2, 0, workers=1, checkpoint_dir=ckpt, chunk=40)
    assert calls == [120] and np.array_equal(again.image, first.image)
    with pytest.raises(CheckpointError, match="other settings"):
        cell_mapping(smap, grid, 3, 0, workers=1, checkpoint_dir=ckpt, chunk=40)
    with pytest.raises(MapError, match="2-D section"):
        cell_mapping(
            StroboscopicMap(load_scenario(SCENARIOS / "jeffcott_rigid_stator.toml").system), grid, 2
        )
    with pytest.raises(ValueError, match="--samples"):
        cell_mapping(smap, grid, 0)
    with pytest.raises(ValueError, match="--region"):
        Grid(4, 4, 1.0, 0.0, 0.0, 1.0)


def test_run_tasks_follows_up_and_saves_every_result(tmp_path):
    ck = Checkpoint(tmp_path / "c", {"a": 1})

    def double(x):
        return {"x": np.array(2 * x)}

    out = run_tasks(
        double,
        [("t_0", (1,))],
        InlineExecutor(),
        ck,
        lambda k, r: (f"t_{int(k[2:]) + 1}", (int(r["x"]),)) if k != "t_2" else None,
        progress=False,
    )
    assert {k: int(v["x"]) for k, v in out.items()} == {"t_0": 2, "t_1": 4, "t_2": 8}
    assert ck.done() == {"t_0", "t_1", "t_2"} and int(ck.load("t_2")["x"]) == 8
    assert Checkpoint(tmp_path / "c", {"a": 1}).done() == ck.done()


def test_parse_param():
    assert parse_param("rotor.speed=300:400:11") == ParamRange("rotor.speed", 300.0, 400.0, 11)
    for bad in (
        "rotor.speed=300:400",
        "speed=1:2:3",
        "rotor.speed=a:2:3",
        "rotor.speed=1:1:5",
        "rotor.speed=1:2:1",
    ):
        with pytest.raises(ScenarioError, match="--param"):
            parse_param(bad)


def test_sweep_shows_the_duffing_hysteresis_by_continuation(tmp_path):
    sc = load_scenario(DUFFING, TWO_WELL)
    param = parse_param("oscillator.forcing_frequency=1.6:2.4:5")
    res = sweep.sweep(
        sc,
        param,
        periods=8,
        discard=150,
        direction="both",
        workers=2,
        block=2,
        checkpoint_dir=tmp_path / "ck",
    )
    at2 = 2  # the value 2.0, where the two attractors coexist
    up, down = res.points["up"][at2, -1], res.points["down"][at2, -1]
    # up the frequency the motion stays on the large branch; down, on the small one
    assert np.allclose(up, LARGE, atol=1e-3) and np.allclose(down, SMALL, atol=1e-3)
    labels = {d: [c["label"] for c in res.classify(d)] for d in ("up", "down")}
    assert labels["up"] == labels["down"] == ["1-0"] * 5
    assert all(res.status[d].tolist() == [0] * 5 for d in ("up", "down"))
    with pytest.raises(ValueError, match="--periods"):
        sweep.sweep(sc, param, periods=1)
    with pytest.raises(ValueError, match="--direction"):
        sweep.sweep(sc, param, direction="sideways")
    with pytest.raises(ScenarioError, match="restitution"):
        sweep.sweep(load_scenario(DUFFING), parse_param("oscillator.restitution=0.5:1.5:3"))


def test_sweep_resumes_without_recomputing(tmp_path, monkeypatch):
    sc = load_scenario(DUFFING)
    param = parse_param("oscillator.forcing_amplitude=0.9:1.1:4")
    kw = {"periods": 4, "discard": 20, "workers": 1, "block": 2, "checkpoint_dir": tmp_path}
    first = sweep.sweep(sc, param, **kw)
    (tmp_path / "up0_00001.npz").unlink()
    calls = []
    real = sweep.run_block
    monkeypatch.setattr(sweep, "run_block", lambda *a: calls.append(len(a[0])) or real(*a))
    again = sweep.sweep(sc, param, **kw)
    assert calls == [2] and np.array_equal(again.points["up"], first.points["up"])
    split = sweep.sweep(sc, param, periods=4, discard=20, workers=1, chains=2)
    assert split.points["up"].shape == (4, 4, 2) and np.all(split.status["up"] == 0)


def test_cli_sweep_writes_data_plot_and_report(tmp_path, capsys):
    out = tmp_path / "sweep"
    args = [
        "sweep",
        str(DUFFING),
        "--param",
        "oscillator.forcing_amplitude=0.8:1.2:4",
        "--periods",
        "6",
        "--discard",
        "120",
        "--direction",
        "both",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-progress",
        "--rtol",
        "1e-8",
        "--chains",
        "1",
        "--plot-state",
        "oscillator.v",
        "--floquet",
        "--lyapunov",
        "--section",
        "impact",
    ]
    assert main(args) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["parameter"] == "oscillator.forcing_amplitude" and len(report["values"]) == 4
    assert [c["label"] for c in report["directions"]["up"]] == ["1-1"] * 4
    for entry in report["directions"]["up"]:  # 1-1 orbits: r^2 exp(-b T) = 0.4675
        re, im = np.array(entry["floquet"]["multipliers"]).T
        assert entry["floquet"]["stable"]
        assert np.prod(re + 1j * im).real == pytest.approx(0.64 * math.exp(-0.1 * math.pi), 1e-6)
        # the largest exponent of a stable 1-1 orbit: ln of its largest multiplier / T
        largest = math.log(np.abs(re + 1j * im).max()) / math.pi
        assert entry["largest_lyapunov_per_s"] == pytest.approx(largest, abs=0.05)
    data = np.load(out / "sweep.npz")
    assert data["points_up"].shape == (4, 6, 2) and (out / "bifurcation.png").stat().st_size
    phases = data["impact_phase_up"]  # one impact a period, at one phase per value
    assert phases.shape == (4, 24) and np.all(np.isfinite(phases[:, :6]))
    assert np.all(np.isnan(phases[:, 6:])) and np.all(np.ptp(phases[:, :6], axis=1) < 1e-6)
    csv = np.loadtxt(out / "sweep.csv", delimiter=",", skiprows=1)
    assert csv.shape == (2 * 4 * 6, 7) and np.all(csv[:, -1] < 0.0)
    assert not (tmp_path / ".sweep.checkpoint").exists()
    assert "swept oscillator.forcing_amplitude" in capsys.readouterr().out
    for bad, msg in [
        (["--param", "oscillator.forcing_amplitude=1:2"], "--param"),
        (["--plot-state", "rotor.x"], "--plot-state"),
        (["--rtol", "5"], "--rtol"),
    ]:
        assert main([*args, *bad]) == 2, bad  # the last of a repeated flag wins
        assert msg in capsys.readouterr().err
    delayed = [
        "sweep",
        str(SCENARIOS / "jeffcott_delayed_feedback.toml"),
        "--param",
        "rotor.speed=300:400:2",
        "--out",
        str(tmp_path / "d"),
    ]
    assert main(delayed) == 2 and "units.controller" in capsys.readouterr().err


def test_cli_basins_writes_data_plot_and_report(tmp_path, capsys):
    out = tmp_path / "basins"
    args = [
        "basins",
        str(DUFFING),
        "--set",
        TWO_WELL[0],
        "--set",
        TWO_WELL[1],
        "--grid",
        "16x16",
        "--samples",
        "3",
        "--region=-4:4,-6:6",
        "--seed",
        "2",
        "--workers",
        "1",
        "--out",
        str(out),
        "--no-progress",
    ]
    assert main(args) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["grid"] == [16, 16] and report["seed"] == 2 and report["samples_per_cell"] == 3
    assert len(report["attractors"]) >= 1 and "cell_numbering" in report
    total = sum(report["counts"]["basins"]) + report["counts"]["boundary"]
    assert total + report["counts"]["escape"] == 256
    data = np.load(out / "basins.npz")
    assert data["labels"].shape == (256,) and data["image"].shape == (256, 3)
    assert (out / "basins.png").stat().st_size > 0
    assert "attractor(s)" in capsys.readouterr().out
    for bad, msg in [
        (["--grid", "16by16"], "--grid"),
        (["--region", "0:1"], "--region"),
        (["--grid", "0x4"], "--grid"),
        (["--samples", "0"], "--samples"),
        (["--workers", "0"], "--workers"),
        (["--seed", "-1"], "--seed"),
    ]:
        assert main([*args, *bad]) == 2, bad
        assert msg in capsys.readouterr().err
    rotor = [
        "basins",
        str(SCENARIOS / "jeffcott_rigid_stator.toml"),
        "--grid",
        "4x4",
        "--samples",
        "1",
        "--region=-1:1,-1:1",
        "--out",
        str(tmp_path / "r"),
    ]
    assert main(rotor) == 2 and "2-D section" in capsys.readouterr().err
    assert main([*args[:-3], "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "s")]) == 2
    assert "--scheduler" in capsys.readouterr().err


LINEAR = ["oscillator.cubic_stiffness=0.0"]  # x'' + 0.1 x' + x = F cos 2t, barrier at 1


def test_grazing_is_located_where_the_free_amplitude_reaches_the_barrier():
    from rubcosim.analysis.grazing import grazing

    g = grazing(load_scenario(DUFFING, LINEAR), "oscillator.forcing_amplitude", 2.5, 3.5)
    # free amplitude F / sqrt((1 - 4)^2 + 0.2^2) = 1 at F = sqrt(9.04)
    assert g.value == pytest.approx(math.sqrt(9.04), rel=1e-8)
    assert abs(g.normal_velocity) < 1e-6
    assert g.exponent == pytest.approx(0.5, abs=0.02)
    assert g.depths.size >= 6 and np.all(np.diff(g.deviations) > 0)


def test_grazing_inputs_are_checked():
    from rubcosim.analysis.errors import AnalysisError
    from rubcosim.analysis.grazing import brackets, free_params, locate

    imp = np.array([[0, 0], [0, 0], [1, 1], [1, 1]])
    assert brackets(np.arange(4.0), imp, np.zeros(4)) == [(1.0, 2.0)]
    assert brackets(np.arange(4.0), imp, np.array([0, 3, 0, 0])) == []
    # an elastic stator grazes too (its law the 3/2 one): taken away by a huge clearance
    elastic = load_scenario(SCENARIOS / "jeffcott_elastic_stator.toml").system
    assert free_params(elastic) == {"stator.clearance": 100.0}
    free = load_scenario(DUFFING, [*LINEAR, "oscillator.stop=none"]).system
    with pytest.raises(AnalysisError, match="oscillator.stop"):
        free_params(free)
    rigid = load_scenario(SCENARIOS / "jeffcott_rigid_stator.toml").system
    assert free_params(rigid) == {"stator.clearance": 100.0}
    with pytest.raises(AnalysisError, match="no grazing there"):
        locate(load_scenario(DUFFING, LINEAR), "oscillator.forcing_amplitude", 1.0, 2.0)


def test_cli_sweep_locates_grazing(tmp_path, capsys):
    out = tmp_path / "g"
    args = [
        "sweep",
        str(DUFFING),
        "--set",
        LINEAR[0],
        "--set",
        "oscillator.x0=0.0",
        "--param",
        "oscillator.forcing_amplitude=2.8:3.2:3",
        "--periods",
        "4",
        "--discard",
        "150",
        "--workers",
        "1",
        "--grazing",
        "--no-progress",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    report = json.loads((out / "report.json").read_text())
    (g,) = report["grazing"]
    assert g["value"] == pytest.approx(math.sqrt(9.04), rel=1e-8)
    assert (out / "grazing.png").stat().st_size > 0
    assert "square-root law exponent 0.5" in capsys.readouterr().out


def test_every_gallery_command_names_a_scenario_and_parses():
    import shlex

    from rubcosim.cli import _parser

    script = (SCENARIOS.parent / "docs" / "make_gallery.sh").read_text()
    commands = script.replace("\\\n", " ").splitlines()
    runs = [shlex.split(c.split("||")[0])[1:] for c in commands if c.startswith("$R ")]
    assert len(runs) == 11
    for argv in runs:
        argv = [a.replace('"$OUT', "results/gallery").rstrip('"') for a in argv if a != "$Q"]
        args = _parser().parse_args(argv)
        assert (SCENARIOS.parent / args.scenario).is_file(), args.scenario
        if args.command == "sweep":
            parse_param(args.param)


def test_delayed_feedback_turns_the_chaotic_rotor_periodic_and_its_force_dies_away():
    from rubcosim.reference.simulate import simulate

    path = SCENARIOS / "jeffcott_chaos_control.toml"
    sc = load_scenario(path, ["sim.rtol=1e-9"])
    T, t_on = sc.system.forcing_period, sc.units["controller"]["t_on"]
    k = np.arange(1, 301)
    res = simulate(sc.system, 300 * T, t_eval=k * T, rtol=1e-9, engine="fast")
    assert res.ok, res.message
    pts = np.column_stack([res.output("rotor.x"), res.output("rotor.y")])
    scale = sc.system.state_scale[:2]
    before = k * T < t_on - 1e-9
    chaos = classify(pts[before][50:], np.zeros(int(before.sum()) - 50), scale)
    assert chaos.label == NOT_PERIODIC and chaos.distinct > 40
    after = classify(pts[-100:], np.zeros(100), scale)
    assert after.period == 1
    # the control force, sampled 40 times a period, dies away on the stabilised orbit
    fine = np.arange(t_on, 300 * T, T / 40)
    u = simulate(sc.system, 300 * T, t_eval=fine, rtol=1e-9, engine="fast")
    force = np.hypot(u.output("controller.ux"), u.output("controller.uy"))
    assert np.max(force[: 20 * 40]) > 10.0
    assert np.max(force[-20 * 40 :]) < 1e-3 * np.max(force[: 20 * 40])
    # without the controller the same rotor stays chaotic
    off = load_scenario(path, ["controller.gain=0.0", "sim.rtol=1e-9"])
    free = simulate(off.system, 300 * T, t_eval=k * T, rtol=1e-9, engine="fast")
    tail = np.column_stack([free.output("rotor.x"), free.output("rotor.y")])[-100:]
    assert classify(tail, np.zeros(100), scale).distinct > 40
