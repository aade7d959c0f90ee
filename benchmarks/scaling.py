"""Scaling and profile of one implicit step (issue 7, item 2), and the MPI check (item 3).

The elastic cantilever of benchmarks/cantilever.py, generalized-alpha, dt = 1e-3, for
n_cells = 1e2 .. 1e5.  Per step and per Newton iteration the wall time is split into
    residual assembly   (BlockSNES's residual callback, incl. its Python),
    Jacobian assembly   (BlockSNES's Jacobian callback; both from TimeStepper.assembly_timings),
    linear solve        (PETSc events PCSetUp + KSPSolve: LU factorisation + solves),
    Python/other        (the rest of the step: stepper bookkeeping, SNES, copies).
JIT: model + step-form construction with an empty FFCx cache (XDG_CACHE_HOME set to a
fresh temporary directory inside the run) vs with the cache warm.

    ./rodenv python3 benchmarks/scaling.py [--quick] [--options KEY=VAL ...]
    ./rodenv mpirun -n 2 python3 benchmarks/scaling.py --mpi-size 100000
Writes results/bench/scaling*.json.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))


def configs():
    """default: Newton + MUMPS; native: PETSc's LU; tuned: native + Jacobian/LU reuse."""
    from dolfin_rod import JACOBIAN_REUSE, NATIVE_LU
    return {"default": None, "native": NATIVE_LU, "tuned": {**NATIVE_LU, **JACOBIAN_REUSE}}


def profiled_run(n_cells: int, steps: int, dt: float = 1e-3, options=None, scene="elastic"):
    """Time `steps` generalized-alpha steps after one start-up step (not timed)."""
    from petsc4py import PETSc
    import cantilever as cant
    from dolfin_rod import TimeStepper

    PETSc.Log.begin()
    t0 = time.perf_counter()
    model = cant.dolfin_rod_model(n_cells, scene)
    stepper = TimeStepper(model.problem, "generalized_alpha", solver_options=options)
    probe = cant.TipProbe(model)
    stepper.step(0.0, dt)                        # start-up step (backward Euler)
    stepper.step(dt, dt)                         # compiles/initialises the main scheme
    t_setup = time.perf_counter() - t0
    events = [PETSc.Log.Event(e) for e in ("KSPSolve", "PCSetUp")]
    ksp0 = sum(e.getPerfInfo()["time"] for e in events)
    before = stepper.assembly_timings()
    its0 = stepper.stats.newton_iterations
    t1 = time.perf_counter()
    for k in range(steps):
        stepper.step((k + 2) * dt, dt)
    wall = time.perf_counter() - t1
    t_ksp = sum(e.getPerfInfo()["time"] for e in events) - ksp0
    timers = {k: v - before[k] for k, v in stepper.assembly_timings().items()}
    its = stepper.stats.newton_iterations - its0
    from mpi4py import MPI
    comm = model.mesh.comm
    wall = comm.allreduce(wall, op=MPI.MAX)
    other = wall - timers["residual"] - timers["jacobian"] - t_ksp
    ndofs = sum(f.function_space.dofmap.index_map.size_global
                * f.function_space.dofmap.index_map_bs for f in model.problem.fields)
    return {"n_cells": n_cells, "dofs": int(ndofs), "ranks": comm.size, "steps": steps,
            "newton_iterations": its, "setup_s": t_setup, "wall_s": wall,
            "per_step_s": wall / steps, "per_iteration_s": wall / max(its, 1),
            "split_s": {"residual_assembly": timers["residual"],
                        "jacobian_assembly": timers["jacobian"],
                        "linear_solve": t_ksp, "python_other": other},
            "tip": probe().tolist(), "options": options or {}}


def jit_cost() -> dict:
    """Model + step-form construction, cold (empty FFCx cache) then warm, in subprocesses."""
    code = ("import sys, time; sys.path.insert(0, %r); t0 = time.perf_counter();"
            "import cantilever as c; from dolfin_rod import TimeStepper;"
            "m = c.dolfin_rod_model(8, 'elastic'); s = TimeStepper(m.problem, 'generalized_alpha');"
            "s.step(0.0, 1e-3); s.step(1e-3, 1e-3); print(time.perf_counter() - t0)"
            % str(Path(__file__).resolve().parent))
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "XDG_CACHE_HOME": cache}
        for label in ("cold", "warm"):
            t0 = time.perf_counter()
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True)
            out[label + "_s"] = float(res.stdout.strip().splitlines()[-1])
            out[label + "_process_s"] = time.perf_counter() - t0
    return out


def main() -> None:
    from mpi4py import MPI
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--mpi-size", type=int, default=0,
                    help="only the MPI check at this size (run under mpirun -n 1 and -n 2)")
    ap.add_argument("--options", nargs="*", default=[], help="PETSc options KEY=VAL")
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    options = dict(kv.split("=", 1) for kv in args.options) or None
    comm = MPI.COMM_WORLD
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    if args.mpi_size:
        from dolfin_rod import JACOBIAN_REUSE  # MUMPS: PETSc's LU is serial
        r = profiled_run(args.mpi_size, 5, options=options or JACOBIAN_REUSE)
        if comm.rank == 0:
            print(json.dumps(r))
            (folder / f"mpi_np{comm.size}{args.tag}.json").write_text(json.dumps(r, indent=1))
        return
    sizes = [100, 1000, 10000] if args.quick else [100, 1000, 10000, 100000]
    rows = []
    runs = configs() if options is None else {"custom": options}
    for (label, opts), n in itertools.product(runs.items(), sizes):
        r = profiled_run(n, 5 if n >= 100000 else 10, options=opts)
        r["config"] = label
        rows.append(r)
        sp = r["split_s"]
        print(f"{label:8s} n={n:7d} dofs={r['dofs']:8d} its/step={r['newton_iterations'] / r['steps']:.1f} "
              f"step={r['per_step_s'] * 1e3:8.2f} ms  it={r['per_iteration_s'] * 1e3:7.2f} ms  "
              + "  ".join(f"{k}={v / r['wall_s'] * 100:4.1f}%" for k, v in sp.items()),
              flush=True)
    out = {"rows": rows, "jit": jit_cost() if not args.tag else None}
    print("JIT (n=8 model + both step forms):", out["jit"])
    (folder / f"scaling{args.tag}.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
