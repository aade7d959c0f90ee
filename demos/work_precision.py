# # Work-precision of the time integrators
#
# Every integrator of dolfin_rod (the per-step schemes of `TimeStepper` and the PETSc TS
# types of `TSIntegrator`) on scenes with a closed-form answer; error at t = 1 against
# `dolfin_rod.closed_forms` is plotted against wall time.  Output:
# `results/work_precision/work_precision.{png,json}`.  Run: `make work-precision`.
#
# ## Scenes
# Homogeneous rod, 4 P1 cells (the twist is linear in s: no space error),
# alpha = 2, alpha_d = 1, mu_d = 0.5.
#
# * relaxation: Phi(t) = 0.5 H(t), mu = 0.  Index-1 DAE; u_d(t) = alpha u0/(alpha + alpha_d)
#   (1 - exp(-k t)), k = (alpha + alpha_d)/mu_d  (eq. stressrelax).
# * creep: m(t) = H(t), mu = 0.5.  (u, u_d) = (I - exp(-tA)) A^{-1}(m0/mu, 0) (eq. creepform,
#   errata 2).
#
# A 3-D dynamic scene will be added by `scene_3d_dynamic` (a stub below): extend SCENES.

from __future__ import annotations

import json
import pathlib
import time

import numpy as np
from mpi4py import MPI

from dolfin_rod import closed_forms as cf
from dolfin_rod import loads
from dolfin_rod.integrators.stepper import TimeStepper
from dolfin_rod.integrators.ts import TSIntegrator
from dolfin_rod.torsion import TorsionModel, TorsionParameters

ALPHA, ALPHA_D, MU_D = 2.0, 1.0, 0.5
OUT = pathlib.Path("results/work_precision")


# A scene returns (problem, error(t_end) callable) fresh for each run.
def scene_relaxation():
    model = TorsionModel(TorsionParameters(ALPHA, ALPHA_D, 0.0, MU_D), n_cells=4,
                         end_rotation=loads.step(0.5))
    model.set_initial_state()

    def error(t):
        u_d, _ = cf.relaxation(t, 0.5, ALPHA, ALPHA_D, MU_D)
        return abs(model.diagnostics(t)["mean_natural_twist"] - u_d)
    return model.problem, error


def scene_creep():
    mu = 0.5
    model = TorsionModel(TorsionParameters(ALPHA, ALPHA_D, mu, MU_D), n_cells=4,
                         end_torsion=loads.step(1.0))
    model.set_initial_state()

    def error(t):
        d = model.diagnostics(t)
        u, u_d = cf.creep(t, 1.0, ALPHA, ALPHA_D, mu, MU_D)
        return max(abs(d["end_rotation"] - u), abs(d["mean_natural_twist"] - u_d))
    return model.problem, error


def scene_3d_dynamic():
    """To be provided by the 3-D engineer: return (problem, error) like the scenes above
    and add it to SCENES (with a reference solution for the error)."""
    raise NotImplementedError


SCENES = {"relaxation": scene_relaxation, "creep": scene_creep}

# ## Integrators
# (label, factory(problem, knob), knobs): knob = dt for fixed-step methods, tolerance for
# adaptive ones.  Explicit Euler needs an ODE (mu > 0) and dt < 2/9.1 (creep_matrix).
DTS = [0.1, 0.05, 0.025, 0.0125, 0.00625]
INTEGRATORS = [
    *[(f"step {s}", (lambda s: lambda p: TimeStepper(p, s))(s), DTS)
      for s in ("backward_euler", "bdf2", "implicit_midpoint", "crank_nicolson",
                "generalized_alpha")],
    ("step explicit_euler", lambda p: TimeStepper(p, "explicit_euler"), DTS[1:]),
    *[(f"ts {s}", (lambda s: lambda p: TSIntegrator(p, s))(s), DTS)
      for s in ("bdf:2", "crank_nicolson", "alpha", "arkimex:l2", "arkimex:3", "arkimex:4")],
]
TOLS = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]


def run_one(scene, make, dt, adaptive_tol=None):
    problem, error = SCENES[scene]()
    integ = (TSIntegrator(problem, "bdf:3", adaptive=True, rtol=adaptive_tol, atol=adaptive_tol)
             if adaptive_tol else make(problem))
    t0 = time.perf_counter()
    integ.run(0.0, 1.0, dt if not adaptive_tol else 1e-4)
    wall = MPI.COMM_WORLD.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    return wall, error(1.0)


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    data = {}
    for scene in SCENES:
        data[scene] = {}
        for label, make, knobs in INTEGRATORS:
            if label == "step explicit_euler" and scene == "relaxation":
                continue  # DAE (mu = 0): no explicit scheme applies
            data[scene][label] = [dict(zip(("dt", "wall", "error"), (k, *run_one(scene, make, k))))
                                  for k in knobs]
        data[scene]["ts bdf:3 adaptive"] = [
            dict(zip(("tol", "wall", "error"), (tol, *run_one(scene, None, None, tol))))
            for tol in TOLS]

    # ## Best method per scene: least wall time with error <= 1e-6
    target = 1e-6
    for scene, runs in data.items():
        ok = [(r["wall"], label, r) for label, rs in runs.items() for r in rs if r["error"] <= target]
        if ok:
            wall, label, r = min(ok, key=lambda x: x[0])
            print(f"{scene}: best to reach error {target:g}: {label} "
                  f"({', '.join(f'{k}={v:.3g}' for k, v in r.items())})")
    if MPI.COMM_WORLD.rank == 0:
        (OUT / "work_precision.json").write_text(json.dumps(data, indent=1))
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(data), figsize=(6 * len(data), 4.5))
        for ax, (scene, runs) in zip(np.atleast_1d(axes), data.items()):
            for label, rs in runs.items():
                ax.loglog([r["wall"] for r in rs], [max(r["error"], 1e-16) for r in rs], "o-",
                          ms=3, label=label)
            ax.set(title=scene, xlabel="wall time [s]", ylabel="error at t = 1")
            ax.grid(True, which="both", alpha=0.3)
        np.atleast_1d(axes)[0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(OUT / "work_precision.png", dpi=110)
        print(f"wrote {OUT}/work_precision.png and .json")


if __name__ == "__main__":
    main()
