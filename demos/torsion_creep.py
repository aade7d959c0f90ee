# # Creep in isolated torsion (Section 5.3, with errata items 2 and 3)
#
# A step end torsion m(t) = m0 H(t) is applied to the quasi-static rod.  With
# Kelvin-Voigt viscosity mu > 0 the twist u and natural twist u_d obey
#
#     d/dt (u, u_d) = -A (u, u_d) + (m/mu, 0),
#     A = [[alpha/mu, -alpha/mu], [-alpha/mu_d, (alpha + alpha_d)/mu_d]],
#
# so (u, u_d) = (I - exp(-tA)) A^{-1} (m0/mu, 0) (eq. creepform), with the matrix
# exponential exp(-tA) = exp(-tau t)[cosh(delta t) I - sinh(delta t)/delta B],
# tau = tr(A)/2, B = A - tau I, delta = sqrt(-det B) (errata item 2: the paper omits
# 1/delta).  With mu = 0 the twist jumps to m0/alpha at once and then creeps,
# u = m0/alpha + (1 - exp(-alpha_d t/mu_d)) m0/alpha_d.  Both tend to
# u = (alpha + alpha_d) m0/(alpha alpha_d), u_d = m0/alpha_d: solid-like creep.
# The rod is the scene `scenes/torsion_creep.toml`, run here as the FE model with the
# load m0 = 0.8 and mu = 0.4 or 0 (changed keys).
# Run: `./rodenv python3 demos/torsion_creep.py`, also under `mpirun -n 2`.

import shutil
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from mpi4py import MPI

from dolfin_rod import closed_forms, load_scene, run

SCENE = "scenes/torsion_creep.toml"
out = Path("results/torsion_creep")
comm = MPI.COMM_WORLD
rank0 = comm.rank == 0
m0, t_end = 0.8, 4.0
scene = load_scene(SCENE)
alpha, alpha_d, mu_d = (scene["material"][k].constant for k in ("alpha", "alpha_d", "mu_d"))


def creep(mu, variant="local"):
    """End rotation (= twist, the rod is homogeneous) and mean natural twist."""
    folder = out / f"mu{mu}_{variant}"
    if rank0:
        shutil.rmtree(folder, ignore_errors=True)
    comm.barrier()
    changes = {"scene.model": "torsion", "material.mu": mu, "material.variant": variant,
               "loads.end_torsion": {"type": "step", "value": m0}, "time.t_end": t_end}
    result = run(SCENE, changes, out=folder, comm=comm, quiet=True)
    assert result.status == "completed", result.summary["message"]
    rows = result.series
    return {k: np.array(rows[k]) for k in ("time", "end_rotation", "mean_natural_twist")}


cases = {"mu = 0.4": creep(0.4), "mu = 0": creep(0.0)}
t = cases["mu = 0"]["time"]
exact = {"mu = 0.4": closed_forms.creep(t, m0, alpha, alpha_d, 0.4, mu_d),
         "mu = 0": closed_forms.creep_inviscid(t, m0, alpha, alpha_d, mu_d)}
uniform = creep(0.4, "uniform")

if rank0:
    columns, header = [t], ["t"]
    fig, ax = plt.subplots(figsize=(6, 4))
    for i, (label, fe) in enumerate(cases.items()):
        u, u_d = exact[label]
        ax.plot(t, u, color=f"C{i}", lw=3, alpha=0.3)
        ax.plot(t, fe["end_rotation"], f"C{i}--", label=f"twist u, {label}")
        ax.plot(t, u_d, color=f"C{i}", lw=3, alpha=0.3)
        ax.plot(t, fe["mean_natural_twist"], f"C{i}:", label=f"natural twist u_d, {label}")
        err = np.max(np.abs(fe["end_rotation"] - u))
        print(f"{label}: max |u_FE - u_exact| = {err:.2e}")
        columns += [fe["end_rotation"], u, fe["mean_natural_twist"], u_d]
        tag = label.replace(" ", "").replace("=", "")
        header += [f"u_{tag}", f"u_exact_{tag}", f"u_d_{tag}", f"u_d_exact_{tag}"]
    u_inf, ud_inf = closed_forms.equilibrium_twists(m0, alpha, alpha_d)
    ax.axhline(u_inf, color="gray", lw=0.8)
    ax.axhline(ud_inf, color="gray", lw=0.8)
    ax.set(xlabel="t", ylabel="twist", title="creep under m0 H(t): FE (dashed) vs closed form")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "creep.png", dpi=120)
    np.savetxt(out / "creep.csv", np.column_stack(columns), delimiter=",", comments="",
               header=",".join(header))
    print(f"uniform vs local (homogeneous rod): max difference "
          f"{np.max(np.abs(uniform['end_rotation'] - cases['mu = 0.4']['end_rotation'])):.1e}")
    print(f"wrote {out / 'creep.png'} and {out / 'creep.csv'}")
