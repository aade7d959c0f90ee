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
# evolution laws part ways.  Run: `./rodenv python3 demos/torsion_relaxation.py`, also
# under `mpirun -n 2`.

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from mpi4py import MPI

from dolfin_rod import closed_forms, loads
from dolfin_rod.integrators.stepper import TimeStepper
from dolfin_rod.torsion import TorsionModel, TorsionParameters

out = Path("results/torsion_relaxation")
rank0 = MPI.COMM_WORLD.rank == 0
u0, t_end, dt = 0.5, 2.0, 0.01


def relax(params, variant, n_cells=32):
    """End torsion and mean natural twist histories after the step Phi = u0 H(t)."""
    model = TorsionModel(params, n_cells=n_cells, variant=variant,
                         end_rotation=loads.step(u0))
    impulse = model.set_initial_state()
    rows = []
    TimeStepper(model.problem, "bdf2").run(
        0.0, t_end, dt, observer=lambda t, s: rows.append(model.diagnostics(t)))
    hist = {k: np.array([r[k] for r in rows])
            for k in ("time", "end_torsion", "mean_natural_twist")}
    return hist, impulse


# ## Homogeneous rod: finite elements against eq. stressrelax
alpha, alpha_d, mu, mu_d = 2.0, 1.0, 0.2, 0.5
fe = {v: relax(TorsionParameters(alpha=alpha, alpha_d=alpha_d, mu=mu, mu_d=mu_d), v)
      for v in ("local", "uniform")}
t = fe["local"][0]["time"]
ud_exact, m_exact = closed_forms.relaxation(t, u0, alpha, alpha_d, mu_d)
errors = {v: float(np.max(np.abs(h["end_torsion"] - m_exact))) for v, (h, _) in fe.items()}

# ## Tapered rod: local and uniform natural twist differ
taper = TorsionParameters(alpha=lambda s: 1 + 3 * s, alpha_d=lambda s: 1 + 3 * s,
                          mu=0.0, mu_d=mu_d)
tapered = {v: relax(taper, v)[0] for v in ("local", "uniform")}

if rank0:
    out.mkdir(parents=True, exist_ok=True)
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
