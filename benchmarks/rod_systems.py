"""Cost of N independent rods in one RodSystem against N times one rod (issue 25).

The elastic gravity cantilever of benchmarks/cantilever.py (32 cells, rotation vectors,
Lie-group generalized-alpha with its defaults, dt = 1e-3), N copies side by side
(0.1 apart along e_1) in one RodSystem: one mesh, one Newton per step for all rods.
Per N: the wall time of 50 steps after a first one (first assembly and symbolic LU
apart), its ratio to N times the single RodModel's, Newton iterations per step, and
the tips' spread (x minus the rod's offset: all equal, 0 up to Newton's tolerance); the
fastest of 3 runs each (the machine is shared).

    ./rodenv python3 benchmarks/rod_systems.py [--rods 1 2 4 8 16] [--steps 50]
Writes results/bench/rod_systems.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cantilever as cant  # noqa: E402

from dolfin_rod import Rod, RodModel, RodSystem, TimeStepper  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
N_CELLS, DT = 32, 1e-3


def build(n_rods: int | None, comm):
    """The cantilever alone (n_rods None: a RodModel) or n_rods of it in a RodSystem."""
    params, model_name, loads = cant.dolfin_rod_parameters(cant.SCENES["elastic"])
    if n_rods is None:
        return RodModel(params, N_CELLS, model=model_name, distributed_loads=loads, comm=comm)
    return RodSystem([Rod(params, N_CELLS, distributed_loads=loads, name=f"rod{k}",
                          position=(0.1 * k, 0.0, 0.0)) for k in range(n_rods)],
                     model=model_name, comm=comm)


def measure(n_rods: int | None, steps: int, comm, repeats: int = 3) -> dict:
    """The fastest of ``repeats`` runs (the machine is shared)."""
    runs = [run(n_rods, steps, comm) for _ in range(repeats)]
    return min(runs, key=lambda row: row["wall_s"])


def run(n_rods: int | None, steps: int, comm) -> dict:
    model = build(n_rods, comm)
    model.set_initial_state()
    integrator = TimeStepper(model.problem)
    integrator.run(0.0, DT, DT)                  # first step apart
    its0 = integrator.stats.newton_iterations
    t0, c0 = time.perf_counter(), time.process_time()
    integrator.run(DT, (steps + 1) * DT, DT)
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
    d = model.diagnostics((steps + 1) * DT)
    tips = [d[k] - 0.1 * i for i, k in enumerate(k for k in d if k.endswith("tip_position_x"))]
    return {"rods": n_rods or 1, "system": n_rods is not None, "wall_s": wall,
            "cpu_s": cpu, "ms_per_step": 1e3 * wall / steps, "cpu_ms_per_step": 1e3 * cpu / steps,
            "newton_per_step": (integrator.stats.newton_iterations - its0) / steps,
            "tip_x": tips[0], "tip_spread": float(np.ptp(tips))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rods", nargs="*", type=int, default=[1, 2, 4, 8, 16])
    ap.add_argument("--steps", type=int, default=50)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    for n in [None, *args.rods]:                 # compile (or load) every structure first
        run(n, 1, comm)
    single = measure(None, args.steps, comm)
    rows = [single]
    for n in args.rods:
        row = measure(n, args.steps, comm)
        row["ratio_to_n_single"] = row["wall_s"] / (n * single["wall_s"])
        row["cpu_ratio_to_n_single"] = row["cpu_s"] / (n * single["cpu_s"])
        rows.append(row)
    if comm.rank == 0:
        for row in rows:
            kind = "RodSystem" if row["system"] else "RodModel "
            print(f"{kind} rods={row['rods']:3d} {row['ms_per_step']:8.3f} ms/step "
                  f"newton/step={row['newton_per_step']:.2f} "
                  f"ratio to N x one rod={row.get('ratio_to_n_single', 1.0):.2f} "
                  f"(cpu {row.get('cpu_ratio_to_n_single', 1.0):.2f}) "
                  f"tip x={row['tip_x']:.12f} spread={row['tip_spread']:.1e}", flush=True)
        load = Path("/proc/loadavg").read_text().split()[:3]
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "rod_systems.json").write_text(
            json.dumps({"rows": rows, "load_average": load}, indent=1))


if __name__ == "__main__":
    main()
