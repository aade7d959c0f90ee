"""Benchmark (not a test): the start of a scene with contact (found by a user trial: the
start, and the settle of initial.equilibrium, ran twice: once while the scene was built,
to refuse a rod starting inside an obstacle before the integrator is compiled, and again
when the run started it).

For each scene, in one process after a first build (warm form caches): ``build`` (the
model, the start made there for its overlap check, the integrator) and ``start`` (the
run's start: the doubled start before, nothing now), the median and least of --repeats
each; the machine's load beside them.  Run it on two trees (this one and an older one,
``--baseline DIR`` holding its dolfin_rod) alternating, so that both see the same load.

    ./rodenv python3 benchmarks/contact_start.py [--repeats 3] [--baseline scratch/base]

Prints the table, writes results/bench/contact_start.json.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("rope_over_boulder.toml", "overhand_knot_tie.toml", "crossing_rods.toml",
          "supercoiled_minicircle.toml")
# the minicircle clamped at its weld and settled (initial.equilibrium, as in
# tests/test_start.py): a start with a settle in contact
SETTLED = {"boundary.start": "clamped", "geometry.n_cells": 24, "initial.equilibrium": True}

ONE_SCENE = """
import json, sys, time
from dolfin_rod import build, load_scene, select_model
path, repeats, overrides = sys.argv[1], int(sys.argv[2]), json.loads(sys.argv[3])
scene = load_scene(path, overrides)
model = select_model(scene).model
build(scene, model).start()                     # compiles, warms the caches
times = {"build": [], "start": []}
for _ in range(repeats):
    t0 = time.perf_counter()
    sim = build(scene, model)
    t1 = time.perf_counter()
    sim.start()
    t2 = time.perf_counter()
    times["build"].append(t1 - t0)
    times["start"].append(t2 - t1)
print(json.dumps(times))
"""


def measure(tree: Path, scene: str, repeats: int) -> dict:
    """{"build": [s], "start": [s]} of ``scene`` with the dolfin_rod of ``tree``."""
    overrides = SETTLED if scene.startswith("supercoiled") else {}
    out = subprocess.run([sys.executable, "-c", ONE_SCENE, str(ROOT / "scenes" / scene),
                          str(repeats), json.dumps(overrides)], cwd=tree, check=True,
                         capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(tree)})   # (cwd: sys.path[0])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--baseline", type=Path, default=None)
    args = parser.parse_args()
    trees = {"this": ROOT, **({"baseline": args.baseline.resolve()} if args.baseline else {})}
    results = {"load_before": os.getloadavg()[0], "repeats": args.repeats, "scenes": {}}
    for scene in SCENES:
        results["scenes"][scene] = {name: measure(tree, scene, args.repeats)
                                    for name, tree in trees.items()}
    results["load_after"] = os.getloadavg()[0]
    print(f"load {results['load_before']:.1f} .. {results['load_after']:.1f}; median (least) s")
    for scene, by_tree in results["scenes"].items():
        for name, times in by_tree.items():
            cells = "  ".join(f"{part} {statistics.median(t):.3f} ({min(t):.3f})"
                              for part, t in times.items())
            print(f"{scene:30s} {name:9s} {cells}")
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "contact_start.json").write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
