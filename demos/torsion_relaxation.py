# # Stress relaxation in isolated torsion (Section 5.2)
#
# A rod, clamped at s = 0, is twisted at t = 0 by a step end rotation
# Phi(t) = u0 H(t) and held.  In the dimensionless, quasi-static model (nu = 0)
#
#     alpha (u - u_d) + mu u_t = m(t),                      (eq. quasistatic)
#     mu_d du_d/dt = alpha (u - u_d) - alpha_d u_d,          (eq. upeq, local variant)
#
# and the homogeneous solution is the paper's eq. stressrelax:
#
#     m(t) = mu u0 delta(t) + alpha alpha_d u0/(alpha + alpha_d)
#            + alpha^2 u0/(alpha + alpha_d) exp(-(alpha + alpha_d) t/mu_d).
#
# The finite-element model (P1 twist angle, DG0 or global natural twist, BDF2 in time)
# resolves the idealised step exactly: the state at t = 0+ is the viscous response to the
# step, and the delta impulse mu u0 is reported apart (TorsionModel.set_initial_state).
# Then a tapered rod (alpha = alpha_d = 1 + 3s) shows where the local and the uniform
# evolution laws part ways.  The rod, load and time stepping are the scene
# `scenes/torsion_relaxation.toml`, run here as the FE model (`scene.model = "torsion"`,
# the scene alone would pick the exact ODE) with mu = 0.2 and changed keys for each case.
# Run: `./rodenv python3 demos/torsion_relaxation.py`, also under `mpirun -n 2`.
# Output: results/torsion_relaxation/{relaxation.csv, relaxation.png} and one run folder
# per case (rod.bp, spacetime.png, timeseries.csv, ...).

import shutil
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from mpi4py import MPI

from dolfin_rod import closed_forms, load_scene, run

SCENE = "scenes/torsion_relaxation.toml"
out = Path("results/torsion_relaxation")
comm = MPI.COMM_WORLD
rank0 = comm.rank == 0
scene = load_scene(SCENE)
u0 = scene["boundary"]["end_rotation"].value
alpha, alpha_d, mu_d = (scene["material"][k].constant for k in ("alpha", "alpha_d", "mu_d"))
mu = 0.2                                   # Kelvin-Voigt viscosity: an impulse mu u0 at 0


def relax(case, **changes):
    """Run the scene as the FE model with ``changes`` (table.key: value); the end torsion
    and mean natural twist histories and the impulse mu u0 of the step at t = 0."""
    folder = out / case
    if rank0:
        shutil.rmtree(folder, ignore_errors=True)
    comm.barrier()
    changes = {"scene.model": "torsion", "geometry.n_cells": 32, "material.mu": mu, **changes}
    result = run(SCENE, changes, out=folder, comm=comm, quiet=True)
    assert result.status == "completed", result.summary["message"]
    hist = {k: np.array(result.series[k]) for k in ("time", "end_torsion", "mean_natural_twist")}
    return hist, result.summary["end_torsion_impulse_at_0"]


# ## Homogeneous rod: finite elements against eq. stressrelax
fe = {v: relax(v, **{"material.variant": v}) for v in ("local", "uniform")}
t = fe["local"][0]["time"]
ud_exact, m_exact = closed_forms.relaxation(t, u0, alpha, alpha_d, mu_d)
errors = {v: float(np.max(np.abs(h["end_torsion"] - m_exact))) for v, (h, _) in fe.items()}

# ## Tapered rod: local and uniform natural twist differ
taper = {"material.alpha": {"polynomial": [1.0, 3.0]},
         "material.alpha_d": {"polynomial": [1.0, 3.0]}, "material.mu": 0.0}
tapered = {v: relax(f"tapered_{v}", **taper, **{"material.variant": v})[0]
           for v in ("local", "uniform")}

if rank0:
    h = fe["local"][0]
    np.savetxt(out / "relaxation.csv",
               np.column_stack([t, h["end_torsion"], fe["uniform"][0]["end_torsion"], m_exact,
                                h["mean_natural_twist"], ud_exact,
                                tapered["local"]["end_torsion"],
                                tapered["uniform"]["end_torsion"]]),
               delimiter=",", comments="",
               header="t,m_local,m_uniform,m_closed_form,u_d_local,u_d_closed_form,"
                      "m_tapered_local,m_tapered_uniform")
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].plot(t, m_exact, "k-", lw=3, alpha=0.3, label="closed form (eq. stressrelax)")
    ax[0].plot(t, h["end_torsion"], "C0--", label="FE, local")
    ax[0].plot(t, fe["uniform"][0]["end_torsion"], "C1:", label="FE, uniform")
    ax[0].axhline(closed_forms.relaxed_torsion(u0, alpha, alpha_d), color="gray", lw=0.8)
    ax[0].set(xlabel="t", ylabel="end torsion m", title=f"homogeneous rod, impulse "
              f"mu u0 = {fe['local'][1]:.3g} at t = 0")
    ax[0].legend()
    ax[1].plot(t, tapered["local"]["end_torsion"], label="local (eq. upeq)")
    ax[1].plot(t, tapered["uniform"]["end_torsion"], label="uniform (errata 1)")
    ax[1].set(xlabel="t", ylabel="end torsion m", title="tapered rod alpha = alpha_d = 1 + 3s")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(out / "relaxation.png", dpi=120)
    print(f"max |m_FE - m_exact|: local {errors['local']:.2e}, uniform {errors['uniform']:.2e}")
    print(f"impulse at t = 0: {fe['local'][1]:.6f} (mu u0 = {mu * u0:.6f})")
    print(f"tapered rod, m(t_end): local {tapered['local']['end_torsion'][-1]:.5f}, "
          f"uniform {tapered['uniform']['end_torsion'][-1]:.5f}")
    print(f"wrote {out / 'relaxation.png'} and {out / 'relaxation.csv'}")
