"""Record every bundled scenario's outputs, or compare a run with such a record.

Guards refactors that must not change results: ``record`` runs each scenario
with the ``fast`` and ``accurate`` engines and the ``direct`` co-simulation and
saves every output on the scenario's output grid (plus event counts) to one
``.npz`` per scenario; ``compare`` re-runs them and prints, per scenario and
engine, the largest difference relative to the recorded output's largest
magnitude, and whether the impact counts agree.

    python benchmarks/scenario_record.py record --out DIR
    python benchmarks/scenario_record.py compare [--record DIR] [names]

``compare`` defaults to the record taken at 7cb116f, before the unit declarations,
the model graph and the shared kernels (``benchmarks/results/scenario_record_7cb116f``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RUNS = ("fast", "accurate", "cosim")
BEFORE_REDESIGN = ROOT / "benchmarks/results/scenario_record_7cb116f"


def _scenarios(names: list[str]) -> list[Path]:
    paths = sorted((ROOT / "scenarios").glob("*.toml"))
    return [p for p in paths if not names or p.stem in names]


def _run(path: Path, how: str) -> dict[str, np.ndarray]:
    from rubcosim.runner import run_cosim_scenario, run_scenario
    from rubcosim.scenario import load_scenario

    sc = load_scenario(path)
    start = time.perf_counter()
    if how == "cosim":
        run = run_cosim_scenario(sc, backend="direct")
        impacts = int(run.result.counters.get("events_impact", 0))
        ok = run.result.ok
    else:
        run = run_scenario(sc, engine=how)
        impacts = int(run.result.counters.get("impacts", run.result.events.of_kind("impact").size))
        ok = run.result.ok
    wall = time.perf_counter() - start
    data = {"t": run.time, "wall_s": np.array(wall), "impacts": np.array(impacts)}
    data["ok"] = np.array(ok)
    for name in sc.outputs:
        data[f"out:{name}"] = run.series(name)
    return data


def record(out: Path, names: list[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    meta = {"commit": commit, "date": time.strftime("%Y-%m-%d %H:%M:%S"), "scenarios": {}}
    for path in _scenarios(names):
        for how in RUNS:
            try:
                data = _run(path, how)
            except Exception as exc:  # a scenario the co-simulation cannot run is recorded so
                meta["scenarios"].setdefault(path.stem, {})[how] = f"error: {exc}"
                print(f"{path.stem:32s} {how:9s} error: {exc}", flush=True)
                continue
            np.savez_compressed(out / f"{path.stem}.{how}.npz", **data)
            meta["scenarios"].setdefault(path.stem, {})[how] = {
                "impacts": int(data["impacts"]),
                "ok": bool(data["ok"]),
                "wall_s": float(data["wall_s"]),
            }
            print(f"{path.stem:32s} {how:9s} impacts {int(data['impacts']):6d}", flush=True)
    (out / "record.json").write_text(json.dumps(meta, indent=1))


def compare(rec: Path, names: list[str]) -> int:
    worst = 0.0
    for path in _scenarios(names):
        for how in RUNS:
            f = rec / f"{path.stem}.{how}.npz"
            if not f.exists():
                continue
            old = np.load(f)
            try:
                new = _run(path, how)
            except Exception as exc:
                print(f"{path.stem:32s} {how:9s} error now: {exc}")
                continue
            rel = 0.0
            where = ""
            for key in old.files:
                if not key.startswith("out:"):
                    continue
                a, b = old[key], new.get(key)
                if b is None:
                    print(f"{path.stem:32s} {how:9s} {key[4:]} no longer recorded")
                    continue
                n = min(a.size, b.size)
                scale = max(float(np.max(np.abs(a))) if a.size else 0.0, 1e-300)
                d = float(np.max(np.abs(a[:n] - b[:n]))) / scale if n else 0.0
                if d > rel:
                    rel, where = d, key[4:]
            if how != "cosim":
                worst = max(worst, rel)
            print(
                f"{path.stem:32s} {how:9s} max rel diff {rel:9.2e} ({where}); impacts "
                f"{int(old['impacts'])} -> {int(new['impacts'])}",
                flush=True,
            )
    print(f"largest relative difference of the engines: {worst:.3g}")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("--out", type=Path, required=True)
    r.add_argument("names", nargs="*", help="scenario names (default: all)")
    c = sub.add_parser("compare")
    c.add_argument("--record", type=Path, default=BEFORE_REDESIGN)
    c.add_argument("names", nargs="*")
    args = ap.parse_args(argv)
    if args.cmd == "record":
        record(args.out, args.names)
        return 0
    return compare(args.record, args.names)


if __name__ == "__main__":
    sys.exit(main())
