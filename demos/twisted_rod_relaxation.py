# # Relaxation of a twisted rod (3-D rod, evolving natural twist)
#
# A straight rubber-like rod of length L, clamped at s = 0, is twisted at t = 0 by a
# quarter turn Phi0 of its end s = L about its own axis e_3 and held there.  The end
# section may slide along the axis (the right end's rotation is prescribed, its position
# is free), so no axial force builds up.  The rod is the paper's (Sections 2-4) with the
# quadratic free energy (eq. quadenergy)
#
#     psi = 1/2 (u - u_d).A(u - u_d) + 1/2 (v - v_d).B(v - v_d) + 1/2 u_d.A_d u_d
#           + 1/2 (v_d - e_3).B_d(v_d - e_3),
#
# no Kelvin-Voigt viscosity (M = N = 0), and either evolution law of the natural strains:
#
#     local   (eq. dotmfupeq):      M_d du_d/dt = -dpsi/du_d = A(u - u_d) - A_d u_d,
#     uniform (eq. dotmfupequnif):  M_d^unif du_d/dt = -int_0^L dpsi/du_d ds.
#
# The uniform viscosity is one for the whole rod: M_d^unif [N m^3 s] = L M_d [N m^2 s]
# relaxes a homogeneous state exactly like the local law with M_d; we use it so.
#
# ## Closed form (Section 5, eq. stressrelax, in dimensional units)
# The twisted rod stays straight and its twist is homogeneous, u = (0, 0, Phi0/L): the
# 3-D problem *is* the isolated-torsion problem, and both laws coincide (homogeneous
# state).  The third components of the laws above are eqs. twist/nattwist with
#
#     alpha = A_33 = GJ,   alpha_d = A_d,33,   mu_d = M_d,33 (= M_d,33^unif / L),
#     u0 = Phi0 / L,   mu = 0,
#
# and these two equations are homogeneous in their units (each term a torque, time
# physical), so closed_forms.relaxation applies to the dimensional stiffnesses as is:
#
#     m(t)   = GJ u0 [A_d,33 + GJ exp(-k t)] / (GJ + A_d,33),   k = (GJ + A_d,33)/M_d,33,
#     u_d(t) = GJ u0 / (GJ + A_d,33) (1 - exp(-k t)).
#
# The end torque drops from GJ u0 to GJ A_d,33 u0 / (GJ + A_d,33) (here: to one third).
# Without Kelvin-Voigt viscosity the response to the step is instantaneously elastic:
# at t = 0+ the rod is uniformly twisted and u_d = 0 (no impulse, mu u0 = 0).
#
# ## Discrete expectations
# * Space: P1 quaternions interpolating a rotation dphi = Phi0/N per element have the
#   midpoint twist u_h = 4 tan(dphi/4)/h = u0 (1 + dphi^2/48 + ...), and the reaction
#   couple (the residual tested with a virtual rotation of the end node) equals the
#   element torque GJ (u_h - u_d) (checked to round-off at t = 0+).  So the space error
#   is the relative dphi^2/48 = 2.0e-4 here (N = 16, dphi = pi/32), and the discrete
#   closed form (u0 -> u_h) removes it, leaving the time error.
# * Time: BDF2 with k dt = 0.025 after one backward-Euler start step: ~(k dt)^2 = 6e-4
#   relative to m(0+).
#
# Run: `./rodenv python3 demos/twisted_rod_relaxation.py`, also under `mpirun -n 2`.
# Output: results/twisted_rod_relaxation/{torque.csv, torque.png, rod_local.bp,
# rod_uniform.bp} (VTX for ParaView: displacement and the director d_1 = R e_1, which
# shows the twist; the natural twist and the torque are in the CSV).

from __future__ import annotations

import pathlib

import dolfinx.fem as fem
import numpy as np
import ufl
from dolfinx.io import VTXWriter
from mpi4py import MPI

from dolfin_rod import closed_forms, compat
from dolfin_rod.integrators.stepper import TimeStepper
from dolfin_rod.rod import RodModel, RodParameters
from dolfin_rod.rotations import np_quaternion_from_rotation_vector, rotation_matrix

OUT = pathlib.Path("results/twisted_rod_relaxation")
comm = MPI.COMM_WORLD
if comm.rank == 0:
    OUT.mkdir(parents=True, exist_ok=True)
comm.barrier()

# ## The rod: a rubber-like cylinder, SI units
# Radius a = 5 mm, E = 3 MPa, G = 1 MPa (incompressible), shear correction 0.9:
# EI = E pi a^4/4, GJ = G pi a^4/2, GA = 0.9 G pi a^2, EA = E pi a^2.  The natural
# configuration has half the elastic stiffness (A_d = A/2, B_d = B/2) and relaxes with
# the time scale tau = 1/k = 20 s in every mode (M_d = tau (A + A_d), N_d = tau (B + B_d)).
L, a, E, G = 0.5, 5e-3, 3e6, 1e6
EI, GJ = E * np.pi * a**4 / 4, G * np.pi * a**4 / 2
GA, EA = 0.9 * G * np.pi * a**2, E * np.pi * a**2
A = np.array([EI, EI, GJ])
B = np.array([GA, GA, EA])
tau = 20.0
params = {variant: RodParameters(length=L, A=A, B=B, A_d=A / 2, B_d=B / 2,
                                 M_d=tau * 1.5 * A * scale, N_d=tau * 1.5 * B * scale)
          for variant, scale in (("local", 1.0), ("uniform", L))}
Phi0, n_cells = np.pi / 2, 16
u0 = Phi0 / L
alpha, alpha_d, mu_d = GJ, 0.5 * GJ, tau * 1.5 * GJ     # the Section 5 coefficients
k = (alpha + alpha_d) / mu_d
t_end, dt = 4 * tau, tau / 40                            # k dt = 0.025
h = L / n_cells
u0_h = 4 * np.tan(Phi0 / n_cells / 4) / h                # the discrete twist (see above)

# Newton: the residual mixes torques ~ GJ u0 = 3e-3 N m with axial forces of a rod with
# EA = 236 N, whose rounding is ~1e-13; absolute 1e-11 is 3e-9 of the torque.
OPTIONS = {"snes_rtol": 1e-10, "snes_atol": 1e-11, "snes_stol": 1e-12}


def end_rotation(t):
    """Phi(t) = Phi0 H(t) about e_3 (the rotation vector superposed on the end section)."""
    return (0.0, 0.0, Phi0 if t >= 0 else 0.0)


def twisted_quaternion(X):
    """Nodal q(s) = exp(s u0 e_3 / 2): the uniformly twisted state at t = 0+."""
    rotvec = np.outer(X[0] * u0, [0.0, 0.0, 1.0])
    return np_quaternion_from_rotation_vector(rotvec).T


def relax(variant):
    """End torque and mean natural twist histories of one variant; writes its VTX file."""
    model = RodModel(params[variant], n_cells=n_cells, variant=variant, ends=("clamped", "free"),
                     end_rotation={"right": end_rotation})
    model.set_initial_state()
    # The state at t = 0+: elastic response to the step, natural strains still those of
    # the straight rod (u_d = 0).  The nodal quaternions are the exact twisted rotations,
    # which is also the discrete equilibrium (all elements alike).
    model.f["quaternion"].interpolate(twisted_quaternion)
    model.f["quaternion"].x.scatter_forward()
    # ... and its rate of natural twist from the evolution law, du_d/dt = GJ u_h / M_d,33
    # (the run starts from rest; this only makes the dissipation rate at t = 0+ right).
    model.r["natural_curvature"].x.array.reshape(-1, 3)[:, 2] = alpha * u0_h / mu_d

    # Fields for ParaView (P1 3-vectors: VTX writes fields of one element): the
    # displacement and the director d_1 = R e_1.
    P1 = model.f["displacement"].function_space
    director = fem.Function(P1, name="director_1")
    d1 = fem.Expression(ufl.dot(rotation_matrix(model.f["quaternion"]),
                                ufl.as_vector((1.0, 0.0, 0.0))),
                        compat.interpolation_points(P1))
    vtx = VTXWriter(comm, OUT / f"rod_{variant}.bp", [model.f["displacement"], director],
                    engine="BP4")
    natural_twist = fem.form(model.f["natural_curvature"][2] * model.dx_r)

    rows = []

    def observe(t, stepper):
        d = model.diagnostics(t)
        d["mean_natural_twist"] = comm.allreduce(fem.assemble_scalar(natural_twist)) / L
        rows.append(d)
        if len(rows) % 20 == 1:
            director.interpolate(d1)
            vtx.write(t)

    TimeStepper(model.problem, "bdf2", solver_options=OPTIONS).run(0.0, t_end, dt, observe)
    vtx.close()
    return {key: np.array([r[key] for r in rows])
            for key in ("time", "reaction_couple_right_z", "mean_natural_twist",
                        "tip_position_x", "tip_position_y", "free_energy",
                        "dissipation_rate")}


hist = {v: relax(v) for v in ("local", "uniform")}

# ## Comparison with the closed form
t = hist["local"]["time"]
ud_exact, m_exact = closed_forms.relaxation(t, u0, alpha, alpha_d, mu_d)
m0 = alpha * u0                                          # m(0+)
ud_h, m_h = closed_forms.relaxation(t, u0_h, alpha, alpha_d, mu_d)
err = {v: float(np.abs(h["reaction_couple_right_z"] - m_exact).max() / m0)
       for v, h in hist.items()}
err_h = {v: float(np.abs(h["reaction_couple_right_z"] - m_h).max() / m0)
         for v, h in hist.items()}
err_ud = {v: float(np.abs(h["mean_natural_twist"] - ud_exact).max() / u0)
          for v, h in hist.items()}
straight = max(float(np.abs(h[f"tip_position_{c}"]).max()) for h in hist.values() for c in "xy")
gap = float(np.abs(hist["local"]["reaction_couple_right_z"]
                   - hist["uniform"]["reaction_couple_right_z"]).max() / m0)
xi_min = min(float(h["dissipation_rate"].min()) for h in hist.values())
# Energy balance (the held end does no work for t > 0): psi(t) + int_0^t xi dt = psi(0+),
# the dissipation integrated by the trapezoidal rule over BDF2's rate estimates.
balance = {v: float(abs(h["free_energy"][-1] + np.trapezoid(h["dissipation_rate"], t)
                        - h["free_energy"][0]) / h["free_energy"][0])
           for v, h in hist.items()}

if comm.rank == 0:
    np.savetxt(OUT / "torque.csv",
               np.column_stack([t, hist["local"]["reaction_couple_right_z"],
                                hist["uniform"]["reaction_couple_right_z"], m_exact, m_h,
                                hist["local"]["mean_natural_twist"],
                                hist["uniform"]["mean_natural_twist"], ud_exact]),
               delimiter=",", comments="",
               header="t,m_local,m_uniform,m_closed_form,m_discrete_closed_form,"
                      "u_d_local,u_d_uniform,u_d_closed_form")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].plot(t, m_exact * 1e3, "k-", lw=3, alpha=0.3, label="closed form (eq. stressrelax)")
    ax[0].plot(t, hist["local"]["reaction_couple_right_z"] * 1e3, "C0--", label="3-D rod, local")
    ax[0].plot(t, hist["uniform"]["reaction_couple_right_z"] * 1e3, "C1:",
               label="3-D rod, uniform")
    ax[0].axhline(closed_forms.relaxed_torsion(u0, alpha, alpha_d) * 1e3, color="gray", lw=0.8)
    ax[0].set(xlabel="t [s]", ylabel="end torque [mN m]",
              title=f"quarter turn held, GJ = {GJ:.3g} N m$^2$")
    ax[0].legend()
    ax[1].plot(t, ud_exact, "k-", lw=3, alpha=0.3, label="closed form")
    ax[1].plot(t, hist["local"]["mean_natural_twist"], "C0--", label="local")
    ax[1].plot(t, hist["uniform"]["mean_natural_twist"], "C1:", label="uniform")
    ax[1].set(xlabel="t [s]", ylabel="natural twist u_d,3 [rad/m]",
              title=f"u0 = Phi0/L = {u0:.3g} rad/m")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(OUT / "torque.png", dpi=110)
    print(f"end torque vs closed form, max error / m(0+): local {err['local']:.2e}, "
          f"uniform {err['uniform']:.2e} (vs discrete closed form: {err_h['local']:.2e}, "
          f"{err_h['uniform']:.2e})")
    print(f"mean natural twist, max error / u0: local {err_ud['local']:.2e}, "
          f"uniform {err_ud['uniform']:.2e}; local - uniform torque {gap:.1e}")
    m_end = hist["local"]["reaction_couple_right_z"][-1]
    print(f"m(0+) = {m0:.4e} N m -> m({t_end:g} s) = {m_end:.4e}"
          f" (relaxed {closed_forms.relaxed_torsion(u0, alpha, alpha_d):.4e}); "
          f"max lateral tip motion {straight:.1e} m")
    print(f"energy balance |psi(T) + int xi dt - psi(0+)| / psi(0+): local "
          f"{balance['local']:.2e}, uniform {balance['uniform']:.2e}; dissipated "
          f"{1 - hist['local']['free_energy'][-1] / hist['local']['free_energy'][0]:.1%} of "
          f"psi(0+) = {hist['local']['free_energy'][0]:.3e} J; min xi {xi_min:.1e} W")
    print(f"wrote {OUT}/torque.csv, torque.png, rod_local.bp, rod_uniform.bp")

# Space dphi^2/48 = 2e-4 plus BDF2's ~(k dt)^2 = 6e-4: allow 1.5e-3; the discrete closed
# form leaves the time error only; the energy balance is BDF2 + trapezoidal, O(dt^2).
assert max(err.values()) < 1.5e-3, err
assert max(err_h.values()) < 1e-3, err_h
assert max(balance.values()) < 1e-3 and xi_min >= -1e-12, (balance, xi_min)
