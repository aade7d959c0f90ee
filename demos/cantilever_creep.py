# # Creep and recovery of a viscoelastic cantilever (3-D rod with evolving natural curvature)
#
# A cantilever of length L = 1 is clamped at s = 0 and loaded at s = L by a dead force
# P e_1 that is switched on at t = 0 and off at t = t_off.  The rod is the paper's
# (Sections 2-4): free energy (eq. quadenergy)
#
#     psi = 1/2 (u - u_d).A(u - u_d) + 1/2 (v - v_d).B(v - v_d) + 1/2 u_d.A_d u_d
#           + 1/2 (v_d - e_3).B_d(v_d - e_3),
#
# Kelvin-Voigt viscosities M, N (eqs. mfmeq, mfneq) and the local evolution laws
# M_d du_d/dt = -dpsi/du_d, N_d dv_d/dt = -dpsi/dv_d (eqs. dotmfupeq, dotmfvpeq).
#
# Check against a closed form.  For a small load the rod is linear and, with B, B_d stiff,
# it bends only: the bending moment m_1(s) = P (L - s) is fixed by statics, so at every s
# the flexural strain obeys the torsion model's 2x2 creep ODE (Section 5, eqs. twist,
# nattwist) with alpha = A_11, alpha_d = A_d,11, mu = M_11, mu_d = M_d,11 and the moment
# m_1(s) as the applied torsion.  Hence the tip deflection is
#
#     delta(t) = P L^3/3 (1 - 1/(4 N^2)) [c(t) - c(t - t_off) H(t - t_off)],
#
# with c(t) the creep compliance u(t)/m_0 of dolfin_rod.closed_forms.creep, and the
# factor (1 - 1/(4N^2)) of the 1-point-Gauss element (see tests/test_rod.py).
#
# Run: `./rodenv python3 demos/cantilever_creep.py` or under `mpirun -n 2`.
# Output: results/cantilever_creep/{rod.bp (ParaView, ADIOS2VTXReader: the deformed rod with
# directors, strains, natural strains, forces, dissipation), animation.gif, snapshots.png,
# tip.png, tip.csv}.  (A scene cannot restart BDF2 at the unloading jump; see below.)

from __future__ import annotations

import pathlib

import numpy as np
from mpi4py import MPI

from dolfin_rod import (closed_forms as cf, EndLoad, FieldOutputs, RodModel, RodParameters,
                        TimeStepper)

OUT = pathlib.Path("results/cantilever_creep")
comm = MPI.COMM_WORLD
if comm.rank == 0:
    OUT.mkdir(parents=True, exist_ok=True)
comm.barrier()

# ## The rod
# Material data per unit length; A_11 = alpha, A_d,11 = alpha_d etc. of the closed form.
alpha, alpha_d, mu, mu_d = 1.0, 0.5, 0.2, 1.0
params = RodParameters(A=(alpha, alpha, 1.0), B=(1e4, 1e4, 1e4),
                       A_d=(alpha_d, alpha_d, 1.0), B_d=(1e4, 1e4, 1e4),
                       M=(mu, mu, 0.1), N=(1e-2, 1e-2, 1e-2),
                       M_d=(mu_d, mu_d, 1.0), N_d=(1.0, 1.0, 1.0))
P, t_off, t_end, dt, n_cells = 1e-3, 4.0, 8.0, 0.02, 32


def switch(t):
    """The load: on during [0, t_off], off afterwards.  Taken left-continuous at t_off
    because the implicit steps evaluate loads at the step's end: the step ending at t_off
    is still loaded, the first step of the second run (below) is not."""
    return 1.0 if t <= t_off else 0.0


model = RodModel(params, n_cells=n_cells, end_loads=[EndLoad("force", (P, 0.0, 0.0), switch)])
model.set_initial_state()

# ## Time integration
# BDF2 (second order, L-stable: the load steps excite no oscillation).  The observer
# records the tip history and writes the rod for ParaView and the animation.
history = []
fields = FieldOutputs(OUT, model, comm)


def observe(t, stepper):
    history.append(model.diagnostics(t))
    if len(history) % 20 == 1:
        fields.write(t)


# Newton stops at |F| < 1e-11 (rounding of the stiff axial terms, EA = 1e4, is ~1e-12).
# The unloading jump at t_off is a restart: a new stepper begins with BDF2's one-step
# start, instead of differencing across the jump of du/dt.
options = {"snes_atol": 1e-11, "snes_stol": 1e-14}
TimeStepper(model.problem, "bdf2", solver_options=options).run(0.0, t_off, dt, observe)
history.pop()  # t_off is recorded again as the start of the second run
TimeStepper(model.problem, "bdf2", solver_options=options).run(t_off, t_end, dt, observe)
fields.finish("cantilever creep and recovery")

# ## Comparison with the closed form
t = np.array([d["time"] for d in history])
tip = np.array([d["tip_position_x"] for d in history])
compliance = cf.creep(t, 1.0, alpha, alpha_d, mu, mu_d)[0]
after = np.where(t >= t_off, cf.creep(np.maximum(t - t_off, 0.0), 1.0, alpha, alpha_d, mu,
                                      mu_d)[0], 0.0)
exact = P / 3 * (1 - 1 / (4 * n_cells**2)) * (compliance - after)
error = np.abs(tip - exact).max() / np.abs(exact).max()
xi = np.array([d["dissipation_rate"] for d in history])
if comm.rank == 0:
    print(f"tip deflection: max {tip.max():.6e}, final {tip[-1]:.3e}; "
          f"max relative error vs closed form {error:.2e} (BDF2, dt = {dt}); "
          f"min dissipation rate {xi.min():.2e} (local model: >= 0)")
    np.savetxt(OUT / "tip.csv", np.c_[t, tip, exact], delimiter=",",
               header="time,tip_deflection,closed_form")
    import matplotlib.pyplot as plt

    plt.figure(figsize=(5.5, 3.5))
    plt.plot(t, tip / (P / 3), label="RodModel (3-D)")
    plt.plot(t, exact / (P / 3), "--", label="closed form (Section 5 creep)")
    plt.axvline(t_off, c="gray", lw=0.5)
    plt.xlabel("t"), plt.ylabel("tip deflection / (P L^3 / 3)")
    plt.title("creep under a tip load, recovery after unloading")
    plt.legend(), plt.tight_layout()
    plt.savefig(OUT / "tip.png", dpi=100)
    print(f"wrote {OUT / 'tip.png'}, {OUT / 'tip.csv'} and {OUT / 'rod.bp'} (ParaView)")
# The error is BDF2's O(dt^2) plus the O(dt) start steps after each load jump: ~1e-3.
assert error < 5e-3, error
