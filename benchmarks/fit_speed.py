"""Benchmark (not a test): `dolfin-rod fit` on the DNA twist example (issue 30, target 4).

Times ``fit_scene`` of examples/fit/dna_twist.toml on examples/fit/dna_twist.csv for
material.viscosity.M_d[2] (docs/fitting.md), each run in its own process (imports
excluded; wall and CPU seconds of the fit), for this tree and, with ``--baseline DIR``
(a folder holding an older ``dolfin_rod`` package, e.g. made by
``git archive COMMIT dolfin_rod | tar -x -C scratch/base``), for that code too,
alternating the two so that both see the same load.  Prints the medians, their ratio,
the machine's load, the estimates of both (they must agree), and writes
results/bench/fit_speed.json.

    ./rodenv python3 benchmarks/fit_speed.py [--baseline scratch/base] [--repeats 2]
                                             [--cells 16]
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
PARAMETER = "material.viscosity.M_d[2]"

ONE_FIT = """
import json, sys, time
from dolfin_rod import fit_scene, load_scene, read_series
scene = load_scene(sys.argv[1], {"geometry.n_cells": int(sys.argv[3])})
data = read_series(sys.argv[2])
wall, cpu = time.perf_counter(), time.process_time()
result = fit_scene(scene, data, [sys.argv[4]])
print(json.dumps({"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu,
                  "value": result.values[0], "std_error": result.std_errors[0],
                  "evaluations": result.evaluations}))
"""


def one_fit(package_folder: Path, cells: int) -> dict:
    """One fit in a new process importing dolfin_rod from ``package_folder``."""
    env = {**os.environ, "PYTHONPATH": str(package_folder)}
    out = subprocess.run([sys.executable, "-c", ONE_FIT,
                          str(ROOT / "examples/fit/dna_twist.toml"),
                          str(ROOT / "examples/fit/dna_twist.csv"), str(cells), PARAMETER],
                         env=env, capture_output=True, text=True, check=True, cwd="/")
    return json.loads(out.stdout.strip().splitlines()[-1])


def summary(runs: list[dict]) -> dict:
    return {"runs": runs, "median_wall_s": statistics.median(r["wall_s"] for r in runs),
            "median_cpu_s": statistics.median(r["cpu_s"] for r in runs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="folder holding an older dolfin_rod")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--cells", type=int, default=16)
    args = parser.parse_args()
    variants = {"this tree": ROOT}
    if args.baseline:
        variants = {"baseline": args.baseline.resolve(), **variants}
    runs = {name: [] for name in variants}
    load = [os.getloadavg()]
    for _ in range(args.repeats):
        for name, folder in variants.items():
            runs[name].append(one_fit(folder, args.cells))
            load.append(os.getloadavg())
    out = {"scene": "examples/fit/dna_twist.toml", "parameter": PARAMETER,
           "n_cells": args.cells, "load_average_1min": [a[0] for a in load],
           "variants": {name: summary(r) for name, r in runs.items()}}
    for name, s in out["variants"].items():
        last = s["runs"][-1]
        print(f"{name:10s} fit {s['median_wall_s']:7.2f} s wall, {s['median_cpu_s']:7.2f} s "
              f"CPU (median of {len(s['runs'])}); M_d[2] = {last['value']!r} +- "
              f"{last['std_error']!r}, {last['evaluations']} model runs")
    if args.baseline:
        base, new = out["variants"]["baseline"], out["variants"]["this tree"]
        out["speedup_wall"] = base["median_wall_s"] / new["median_wall_s"]
        out["speedup_cpu"] = base["median_cpu_s"] / new["median_cpu_s"]
        out["same_estimate"] = all(
            abs(b["value"] - n["value"]) <= 1e-9 * abs(b["value"])
            for b, n in zip(base["runs"], new["runs"]))
        print(f"speed-up {out['speedup_wall']:.2f}x wall, {out['speedup_cpu']:.2f}x CPU; "
              f"same estimate (1e-9 relative): {out['same_estimate']}")
    print("load average (1 min) during the runs:", " ".join(f"{a:.1f}" for a in
                                                             out["load_average_1min"]))
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "fit_speed.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {folder / 'fit_speed.json'}")


if __name__ == "__main__":
    main()
