# # A flexible rod swinging under gravity (3-D dynamics, large rotations)
#
# A rod of length L = 1 m is pinned at s = 0 (position fixed, rotation free: a ball
# joint), held horizontal along e_3 and released at t = 0 in gravity g = -g e_1, with a
# sideways spin w0 about the vertical e_1 so that it swings out of its initial vertical
# plane (a flexible spherical pendulum).  It falls ~70 degrees below the horizontal while
# sweeping half-way round the pin (the end section turns by ~200 degrees), bends and
# twists on the way, and its natural curvature evolves (creeps) meanwhile.
#
# ## Balance laws (Section 2.2, eqs. linmom and angmom)
#
#     rho A r_tt = n_s + f,       d/dt[(rho J) w] = m_s + r_s x n,       f = -rho A g e_1,
#
# written first order (velocity V = x_t and material angular velocity W = 2 vec(q* q_t)
# are fields, balance.py), with the paper's constitutive laws: the quadratic free energy
# psi(u_d, v_d, u, v) of eq. quadenergy and the local evolution laws of the natural
# strains M_d du_d/dt = -dpsi/du_d, N_d dv_d/dt = -dpsi/dv_d (eqs. dotmfupeq,
# dotmfvpeq).  These are the only dissipation: xi = u_d,t . M_d u_d,t + v_d,t . N_d
# v_d,t >= 0 (eq. disspw; no Kelvin-Voigt viscosity, no drag).
#
# ## Energy balance
# Testing the balance laws with the velocities gives (docs/corrections.md identities)
#
#     d/dt (K + Psi + U_g) = -Xi,   K = 1/2 int rho A V.V + W.J W ds,  Psi = int psi ds,
#     U_g = int rho A g e_1 . r ds,  Xi = int xi ds,
#
# so E(t) + D(t) with D(t) = int_0^t Xi dt is constant.  Implicit midpoint keeps it to
# O(dt^2) (it is exact for quadratic energies only; rotations and the quaternion
# constraint make psi non-quadratic); we measure the defect
#
#     |E(t) + D(t) - E(0)| / max_t K(t),
#
# with D by the trapezoidal rule over the scheme's rate estimates, at two time steps to
# show its order (the error of the demo's run is the larger one).
#
# Run: `./rodenv python3 demos/swinging_rod.py` (about 12 s), also under `mpirun -n 2`.
# Output: results/swinging_rod/{energy.csv, energy.png, centreline.png, rod.bp (ParaView,
# ADIOS2VTXReader: the deformed rod with directors, strains, forces), animation.gif,
# snapshots.png}.  (The initial spin is set through the Python API: scenes start at rest.)

from __future__ import annotations

import pathlib
import time

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from dolfin_rod import DistributedLoad, FieldOutputs, RodModel, RodParameters, TimeStepper

OUT = pathlib.Path("results/swinging_rod")
comm = MPI.COMM_WORLD
if comm.rank == 0:
    OUT.mkdir(parents=True, exist_ok=True)
comm.barrier()

# ## The rod (SI units)
# Mass 1 kg/m, EI = 1 N m^2: gravity bends it visibly (rho A g L^3 / EI ~ 10), the first
# pinned-free bending mode (~2.4 Hz) is excited by the swing.  Shear and axial stiffness
# 500 and 1000 N; rotary inertia of a solid section of radius 6 cm (rho I = rho A a^2/4).
# The natural configuration is as stiff as the elastic one and relaxes in tau = 1 s.
L, g, rho_A, w0 = 1.0, 9.81, 1.0, 2.0
A = np.array([1.0, 1.0, 0.8])
B = np.array([500.0, 500.0, 1000.0])
tau = 1.0
I_sec = rho_A * 0.06**2 / 4
params = RodParameters(length=L, A=A, B=B, A_d=A, B_d=B, M_d=2 * tau * A, N_d=2 * tau * B,
                       density=rho_A, section_inertia=I_sec)
gravity = DistributedLoad("force", (-rho_A * g, 0.0, 0.0))
n_cells, t_end = 16, 1.5
# Newton: residual entries are forces ~ rho A g h = 0.6 N next to B = 1e3 N stiffnesses.
OPTIONS = {"snes_rtol": 1e-10, "snes_atol": 1e-10, "snes_stol": 1e-12}


def build():
    """The rod at rest in its straight, horizontal natural state, then set spinning:
    V = w0 e_1 x r (rigid rotation about the vertical through the pin), W = R^T w0 e_1."""
    # implicit midpoint advances the quaternion form (the default for a dynamic rod,
    # rotation vectors, is advanced by generalized-alpha on the rotation group)
    model = RodModel(params, n_cells=n_cells, start="pinned", end="free",
                     distributed_loads=[gravity], rotations="quaternion")
    model.set_initial_state()
    model.f["velocity"].interpolate(
        lambda X: np.cross([w0, 0.0, 0.0], np.c_[0 * X[0], 0 * X[0], X[0]]).T)
    model.f["angular_velocity"].interpolate(
        lambda X: np.outer([w0, 0.0, 0.0], np.ones_like(X[0])))
    return model


def swing(scheme, dt, record=None):
    """Run one simulation; returns the energy history (and writes output if asked)."""
    model = build()
    s = ufl.SpatialCoordinate(model.mesh)[0]
    r = ufl.as_vector((0.0, 0.0, s)) + model.f["displacement"]
    U_g = fem.form(rho_A * g * r[0] * model.dx)          # gravity potential
    rows = []
    if record:   # rod.bp (the deformed rod for ParaView) and the animation
        fields = FieldOutputs(OUT, model, comm)
        P1 = model.f["displacement"].function_space
        nodes = P1.tabulate_dof_coordinates()[:P1.dofmap.index_map.size_local, 0]
        snapshots = []

    def observe(t, stepper):
        d = model.diagnostics(t)
        d["gravity_potential"] = comm.allreduce(fem.assemble_scalar(U_g))
        rows.append(d)
        if record and (len(rows) - 1) % record == 0:
            fields.write(t)
            n = len(nodes)
            xs = model.f["displacement"].x.array[:3 * n].reshape(-1, 3).copy()
            xs[:, 2] += nodes
            parts = comm.gather((nodes, xs), root=0)
            if comm.rank == 0:
                sn = np.concatenate([p[0] for p in parts])
                order = np.argsort(sn)
                snapshots.append((t, np.concatenate([p[1] for p in parts])[order]))

    t0 = time.perf_counter()
    stepper = TimeStepper(model.problem, scheme, solver_options=OPTIONS)
    stepper.run(0.0, t_end, dt, observe)
    wall = time.perf_counter() - t0
    if record:
        fields.finish("swinging rod")
    h = {k: np.array([row[k] for row in rows]) for k in rows[0]}
    t = h["time"]
    h["dissipated"] = np.concatenate([[0.0], np.cumsum(
        0.5 * (h["dissipation_rate"][1:] + h["dissipation_rate"][:-1]) * np.diff(t))])
    h["total"] = h["kinetic_energy"] + h["free_energy"] + h["gravity_potential"]
    h["defect"] = np.abs(h["total"] + h["dissipated"] - h["total"][0]) / h["kinetic_energy"].max()
    h["wall"], h["newton"] = wall, stepper.stats.newton_iterations
    return h, (snapshots if record else None)


# ## The run, and the energy defect at half the step
dt = 0.01
hist, snapshots = swing("implicit_midpoint", dt, record=10)
fine, _ = swing("implicit_midpoint", dt / 2)
defect, defect_fine = hist["defect"].max(), fine["defect"].max()
tip = np.c_[hist["tip_position_x"], hist["tip_position_y"], hist["tip_position_z"]]
angle = np.degrees(np.arctan2(-tip[:, 0], np.hypot(tip[:, 1], tip[:, 2])))  # below horizontal
t = hist["time"]

if comm.rank == 0:
    cols = ["time", "kinetic_energy", "free_energy", "gravity_potential", "dissipated",
            "total", "defect", "tip_position_x", "tip_position_y", "tip_position_z",
            "tip_rotation_angle"]
    np.savetxt(OUT / "energy.csv", np.column_stack([hist[c] for c in cols]), delimiter=",",
               comments="", header=",".join(cols))
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for key, label in (("kinetic_energy", "kinetic K"), ("free_energy", "free energy Psi"),
                       ("gravity_potential", "gravity U_g"), ("dissipated", "dissipated D"),
                       ("total", "K + Psi + U_g")):
        ax[0].plot(t, hist[key] - (hist[key][0] if key == "gravity_potential" else 0),
                   label=label)
    ax[0].plot(t, hist["total"] + hist["dissipated"], "k--", label="K + Psi + U_g + D")
    ax[0].set(xlabel="t [s]", ylabel="energy [J] (U_g from its initial value)",
              title="energy balance, implicit midpoint")
    ax[0].legend(fontsize=8)
    ax[1].semilogy(t[1:], hist["defect"][1:], label=f"dt = {dt}")
    ax[1].semilogy(fine["time"][1:], fine["defect"][1:], label=f"dt = {dt / 2}")
    ax[1].set(xlabel="t [s]", ylabel="|E + D - E(0)| / max K", title="energy defect")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(OUT / "energy.png", dpi=110)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    colors = plt.cm.viridis(np.linspace(0, 1, len(snapshots)))
    for (ts, xs), c in zip(snapshots, colors):
        ax[0].plot(xs[:, 2], xs[:, 0], color=c, lw=1.2)
        ax[1].plot(xs[:, 2], xs[:, 1], color=c, lw=1.2)
    ax[0].set(xlabel="e_3 [m]", ylabel="e_1 (up) [m]", title="side view", aspect="equal")
    ax[1].set(xlabel="e_3 [m]", ylabel="e_2 [m]", title="top view", aspect="equal")
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=plt.Normalize(0, t_end))
    fig.colorbar(sm, ax=ax, label="t [s]")
    fig.savefig(OUT / "centreline.png", dpi=110)

    print(f"swing: tip falls to {angle.max():.0f} deg below horizontal, swings "
          f"{np.abs(tip[:, 1]).max():.2f} m sideways; tip rotation up to "
          f"{np.degrees(hist['tip_rotation_angle'].max()):.0f} deg")
    print(f"energy: max K = {hist['kinetic_energy'].max():.3f} J, max Psi = "
          f"{hist['free_energy'].max():.3f} J, dissipated D(T) = {hist['dissipated'][-1]:.3f} J")
    print(f"energy defect max |E + D - E(0)| / max K: {defect:.2e} (dt = {dt}), "
          f"{defect_fine:.2e} (dt = {dt / 2}); order {np.log2(defect / defect_fine):.2f}")
    print(f"implicit midpoint, {n_cells} cells: {len(t) - 1} steps, {hist['newton']} Newton "
          f"iterations, {hist['wall']:.1f} s")
    print(f"wrote {OUT}/energy.csv, energy.png, centreline.png, rod.bp, animation.gif")

# Second order: halving dt divides the defect by ~4; a wrong inertia, load or dissipation
# term would leave an O(1) defect that does not converge.
assert defect < 2e-2 and defect / defect_fine > 3.0, (defect, defect_fine)
