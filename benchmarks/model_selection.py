"""Benchmark (not a test): the reduced ODE vs the torsion PDE on the same scenes.

For each bundled torsion scene the least model is the ODE (eqs. twist/nattwist).  Time
    ode-exact    closed form / solve_ivp at the output times,
    ode-scheme   the FE scheme applied to the 2x2 system,
    torsion      the isolated-torsion PDE (TorsionModel + TimeStepper), n_cells = 8, 64,
and record the maximum deviation of the end torsion and end rotation from ode-exact.
Writes results/bench/model_selection.json.  Run: ./rodenv python3 benchmarks/model_selection.py
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from mpi4py import MPI

from dolfin_rod import build, load_scene, versions

ROOT = Path(__file__).resolve().parents[1]


def run(scene, model):
    t0 = time.perf_counter()
    sim = build(scene, model)
    sim.start()
    t_setup = time.perf_counter() - t0
    dt, t_end = scene["time"]["dt"], scene["time"]["t_end"]
    n = round(t_end / dt)
    rows = [sim.diagnostics(0.0)]
    for k in range(1, n + 1):
        sim.advance((k - 1) * dt, k * dt)
        rows.append(sim.diagnostics(k * dt))
    total = time.perf_counter() - t0
    return rows, {"setup_s": t_setup, "total_s": total, "steps": n}


def main() -> None:
    comm = MPI.COMM_WORLD
    out = {"versions": versions(), "ranks": comm.size, "cases": []}
    for name in ("torsion_relaxation.toml", "torsion_creep.toml"):
        for label, model, mode, cells in (("ode-exact", "ode", "exact", None),
                                          ("ode-scheme", "ode", "scheme", None),
                                          ("torsion-8", "torsion", "exact", 8),
                                          ("torsion-64", "torsion", "exact", 64)):
            scene = load_scene(ROOT / "scenes" / name)
            scene["time"]["ode_solution"] = mode
            if cells:
                scene["geometry"]["n_cells"] = cells
            run(scene, model)  # warm-up: JIT compilation is cached after the first run
            rows, timing = run(scene, model)
            if label == "ode-exact":
                reference = rows
            dev = {k: max(abs(a[k] - b[k]) for a, b in zip(rows, reference))
                   for k in ("end_torsion", "end_rotation", "mean_natural_twist")}
            case = {"scene": name, "model": label, **timing, "max_deviation_from_exact": dev}
            out["cases"].append(case)
            if comm.rank == 0:
                print(f"{name:26s} {label:11s} {timing['total_s'] * 1e3:9.2f} ms  "
                      f"max |dm| = {dev['end_torsion']:.2e}  max |du| = {dev['end_rotation']:.2e}")
    if comm.rank == 0:
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "model_selection.json").write_text(json.dumps(out, indent=1))
        print(f"wrote {folder / 'model_selection.json'}")


if __name__ == "__main__":
    main()
