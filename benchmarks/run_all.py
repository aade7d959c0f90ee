"""`make bench`: every benchmark of issue 7, JSON and PNG under results/bench/.

    ./rodenv python3 benchmarks/run_all.py           # full (about 10-15 min on 2 cores)
    ./rodenv python3 benchmarks/run_all.py --quick   # smaller sizes (a few minutes)

0. defaults.py         what a user gets without options: per step, set-up, the CLI run
   quasi_static.py      quasi-static rods' defaults (rotation vectors) vs quaternions
   rod_scaling.py       cost per cell and Newton iteration at 1e3..1e5 cells (defaults),
                        1 and 2 ranks at 1e5 cells (the MPI speed-up, identical tips)
1. peer_pyelastica.py   work-precision vs PyElastica on six gravity-cantilever scenes
   peer_pyelastica_long.py  part "peer_long": the creep_long scene (tau = 10 s, T = 30 s,
                        same drag on both sides; ~10 min, PyElastica dominates)
2. scaling.py           time per step / Newton iteration, 1e2 .. 1e5 cells, split into
                        assembly, linear solve, Python; JIT cold vs warm
3. MPI                  scaling.py --mpi-size N under mpirun -n 1 and -n 2: speed-up and
                        the tip-position difference (N = 1e5, 2e4 with --quick)
4. model_selection.py   reduced ODE vs torsion PDE on the torsion scenes (a colleague's)
Absolute times are noisy on a shared machine; compare ratios from one run.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "results" / "bench"


def run(cmd):
    print("$", " ".join(cmd), flush=True)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=HERE.parent)
    return time.perf_counter() - t0


def plot_scaling(path_json, path_png):
    import matplotlib.pyplot as plt
    rows = json.loads(path_json.read_text())["rows"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for label, mk in (("default", "o"), ("native", "^"), ("tuned", "s")):
        rr = [r for r in rows if r["config"] == label]
        if not rr:
            continue
        n = [r["n_cells"] for r in rr]
        axes[0].loglog(n, [r["per_step_s"] for r in rr], marker=mk, label=f"per step ({label})")
        axes[0].loglog(n, [r["per_iteration_s"] for r in rr], marker=mk, ls="--",
                       label=f"per Newton iteration ({label})")
    axes[0].loglog([1e2, 1e5], [1e-3, 1.0], color="0.7", lw=0.8, label="O(n)")
    axes[0].set_xlabel("cells")
    axes[0].set_ylabel("wall time [s]")
    axes[0].legend(fontsize=8)
    axes[0].grid(True, which="both", alpha=0.3)
    keys = ["residual_assembly", "jacobian_assembly", "linear_solve", "python_other"]
    labels = [f"{r['config'][0]}:{r['n_cells']:.0e}" for r in rows]
    bottom = np.zeros(len(rows))
    for k in keys:
        frac = np.array([r["split_s"][k] / r["wall_s"] for r in rows])
        axes[1].bar(labels, frac, bottom=bottom, label=k)
        bottom += frac
    axes[1].set_ylabel("fraction of step time")
    axes[1].set_title("d: default (Newton, MUMPS), n: native LU, t: native + reuse")
    axes[1].tick_params(axis="x", rotation=45, labelsize=7)
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path_png, dpi=120)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--parts", nargs="*",
                    default=["defaults", "quasi_static", "rod_scaling", "peer", "peer_long",
                             "scaling", "mpi", "model_selection"])
    args = ap.parse_args()
    quick = ["--quick"] if args.quick else []
    py = sys.executable
    OUT.mkdir(parents=True, exist_ok=True)
    wall = {}
    if "defaults" in args.parts:
        wall["defaults"] = run([py, str(HERE / "defaults.py")])
    if "quasi_static" in args.parts:
        wall["quasi_static"] = run([py, str(HERE / "quasi_static.py"), *quick])
    if "rod_scaling" in args.parts:
        sizes = ["--sizes", *(["1000", "20000"] if args.quick else ["1000", "10000", "100000"])]
        wall["rod_scaling"] = run([py, str(HERE / "rod_scaling.py"), *sizes])
        wall["rod_scaling_np2"] = run(["mpirun", "-n", "2", py, str(HERE / "rod_scaling.py"),
                                       "--sizes", sizes[-1]])
    if "peer" in args.parts:
        wall["peer_pyelastica"] = run([py, str(HERE / "peer_pyelastica.py"), *quick])
    if "peer_long" in args.parts:
        wall["peer_pyelastica_long"] = run([py, str(HERE / "peer_pyelastica_long.py"), *quick])
    if "scaling" in args.parts:
        wall["scaling"] = run([py, str(HERE / "scaling.py"), *quick])
        plot_scaling(OUT / "scaling.json", OUT / "scaling.png")
    if "mpi" in args.parts:
        run_mpi(args, py, wall)
    if "model_selection" in args.parts:
        wall["model_selection"] = run([py, str(HERE / "model_selection.py")])
    (OUT / "run_all.json").write_text(json.dumps({"quick": args.quick, "wall_s": wall}, indent=1))
    print("bench wall times [s]:", {k: round(v, 1) for k, v in wall.items()})


def run_mpi(args, py, wall):
    n_mpi = 20000 if args.quick else 100000
    mpi = {"n_cells": n_mpi}
    for np_ in (1, 2):
        wall[f"mpi_np{np_}"] = run(["mpirun", "-n", str(np_), py, str(HERE / "scaling.py"),
                                    "--mpi-size", str(n_mpi)])
        mpi[f"np{np_}"] = json.loads((OUT / f"mpi_np{np_}.json").read_text())
    mpi["speedup_per_step"] = mpi["np1"]["per_step_s"] / mpi["np2"]["per_step_s"]
    mpi["max_tip_difference"] = float(np.max(np.abs(np.subtract(mpi["np1"]["tip"],
                                                                mpi["np2"]["tip"]))))
    mpi["newton_iterations"] = [mpi["np1"]["newton_iterations"], mpi["np2"]["newton_iterations"]]
    (OUT / "mpi.json").write_text(json.dumps(mpi, indent=1))
    print(f"MPI n={n_mpi}: speed-up (1 -> 2 ranks) per step {mpi['speedup_per_step']:.2f}, "
          f"max |tip difference| = {mpi['max_tip_difference']:.2e}")


if __name__ == "__main__":
    main()
