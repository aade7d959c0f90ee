"""Cost per cell and Newton iteration of the dynamic rod with its defaults (issue 12:
rotation vectors, 6 unknowns per node).

Elastic cantilever (benchmarks/cantilever.py), Lie-group generalized-alpha, dt = 1e-3,
a few steps per size after a first one (first assembly and symbolic LU factorisation,
reported apart); split into residual assembly, Jacobian assembly and the rest (LU
factorisation + solve + SNES/Python), per cell per Newton iteration, CPU time beside
wall time (the machine may be shared).  Beside each
number its physical limit: flops of the block-tridiagonal LU for b unknowns per node,
flops of the Jacobian kernel (counted in the generated C) and bytes of assembly.
Also the set-up time of a model whose structure is compiled already (form_cache) and,
under mpirun, the tip position (serial == 2 ranks).

    ./rodenv python3 benchmarks/rod_scaling.py [--sizes 1000 10000 100000]
    ./rodenv mpirun -n 2 python3 benchmarks/rod_scaling.py --sizes 100000
Writes results/bench/rod_scaling_np{size}.json.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cantilever as cant  # noqa: E402

from dolfin_rod import TimeStepper  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def kernel_flops(form) -> int:
    """Multiplications and additions in the generated C of a compiled form's kernels."""
    source = Path(form.module.__file__).with_suffix("").with_suffix(".c")
    if not source.exists():
        candidates = list(Path(form.module.__file__).parent.glob(
            Path(form.module.__file__).name.split(".")[0] + ".c"))
        if not candidates:
            return -1
        source = candidates[0]
    body = source.read_text()
    return len(re.findall(r"[^+*/-][*+-][^+*/=-]", body))


def lu_flops_per_node(b: int) -> float:
    """Block-tridiagonal LU, b x b blocks: LU of the pivot block 2/3 b^3, the multiplier
    C D^-1 2 b^3, the Schur update 2 b^3."""
    return (2 / 3 + 2 + 2) * b**3


def measure(n_cells: int, steps: int, comm) -> dict:
    t0 = time.perf_counter()
    model = cant.dolfin_rod_model(n_cells, "elastic", comm)
    integrator = TimeStepper(model.problem)     # every default
    integrator.initial_accelerations(0.0)
    setup = time.perf_counter() - t0
    probe = cant.TipProbe(model)
    # the first step (first assembly, symbolic LU factorisation) apart: steady state below
    t0 = time.perf_counter()
    integrator.run(0.0, 1e-3, 1e-3)
    first = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    its0 = integrator.stats.newton_iterations
    timings, counts = integrator.solver.timings, integrator.solver.counts
    timings.update(residual=0.0, jacobian=0.0)
    counts.update(residual=0, jacobian=0)
    t0, c0 = time.perf_counter(), time.process_time()
    t = integrator.run(1e-3, (steps + 1) * 1e-3, 1e-3)
    wall = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    cpu = comm.allreduce(time.process_time() - c0, op=MPI.MAX)
    its = integrator.stats.newton_iterations - its0
    per = 1e6 / (its * n_cells)
    res = comm.allreduce(timings["residual"], op=MPI.MAX)
    jac = comm.allreduce(timings["jacobian"], op=MPI.MAX)
    out = {"n_cells": n_cells, "ranks": comm.size, "unknowns": integrator.solver.x.getSize(),
           "setup_s": setup, "first_step_s": first, "steps": steps, "newton_iterations": its,
           "jacobians": counts["jacobian"], "residuals": counts["residual"],
           "wall_s": wall, "cpu_s": cpu, "us_per_cell_iteration": wall * per,
           "cpu_us_per_cell_iteration": cpu * per,
           "residual_us": res * per, "jacobian_us": jac * per,
           "jacobian_us_per_assembly": jac * 1e6 / (max(counts["jacobian"], 1) * n_cells),
           "solve_and_rest_us": (wall - res - jac) * per, "tip": probe().tolist(), "t": t}
    if comm.rank == 0:
        print(f"n={n_cells:7d} ranks={comm.size} setup={setup:.3f} s first step={first:.3f} s "
              f"its/step={its / steps:.2f} jacobians={counts['jacobian']} "
              f"total={out['us_per_cell_iteration']:.2f} "
              f"(cpu {out['cpu_us_per_cell_iteration']:.2f}) "
              f"res={out['residual_us']:.2f} jac={out['jacobian_us']:.2f} "
              f"({out['jacobian_us_per_assembly']:.2f} per assembly) "
              f"solve+rest={out['solve_and_rest_us']:.2f} us/cell/iteration", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", nargs="*", type=int, default=[1000, 10000, 100000])
    ap.add_argument("--steps", type=int, default=3)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    measure(8, 1, comm)                        # compiles (or loads) the forms: excluded
    rows = [measure(n, args.steps, comm) for n in args.sizes]
    model = cant.dolfin_rod_model(8, "elastic", comm)
    integrator = TimeStepper(model.problem)
    limits = {"unknowns_per_node": 6,
              "lu_flops_per_node": lu_flops_per_node(6),
              "jacobian_kernel_flops": [kernel_flops(f) for f in integrator.solver.system.J],
              "element_matrix_bytes": 12 * 12 * 8}
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    if comm.rank == 0:
        print("limits:", limits, "load average:", load)
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / f"rod_scaling_np{comm.size}.json").write_text(
            json.dumps({"rows": rows, "limits": limits, "load_average": load}, indent=1))


if __name__ == "__main__":
    main()
