# # A rope dropped on a floor with friction (contact with obstacles, docs/contact.md)
#
# scenes/rope_on_floor.toml: a soft rope (L = 1 m, radius 5 mm, 80 g/m) straight along
# e_3 at t = 0 falls under gravity g = -9.81 e_1 onto a floor tilted by 11 degrees, end
# s = L first; it whips down, slides and comes to rest held by Coulomb friction
# (mu = 0.5 > tan 11 deg).  The floor is a smooth barrier of gap delta = 0.5 mm with the
# default stiffness (from rho A / dt^2 and EI / h^4); friction is smoothed below the slip
# tolerance eps = 1 mm/s.
#
# Checks (the run's own time series):
#   - the floor never lets the rope through: min_gap > 0 at every step;
#   - at rest the floor carries the weight: contact force = rho A g L e_1 to 1e-4;
#   - friction only dissipates: friction_dissipation >= 0 at every step;
#   - held by friction: the rope creeps slower than eps.
#
# Run: `./rodenv python3 demos/rope_on_floor.py` (~1 min), also under `mpirun -n 2`.
# Output: results/rope_on_floor/ (the run folder: timeseries.csv, rod.bp with the
# contact force along the rope, animation.gif, snapshots.png) and contact.png.

from __future__ import annotations

import pathlib

import numpy as np
from mpi4py import MPI

from dolfin_rod import load_scene, run_scene

OUT = pathlib.Path("results/rope_on_floor")
WEIGHT = 0.08 * 9.81          # rho A g L (N)


def read_series(path: pathlib.Path) -> dict:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: data[name] for name in data.dtype.names}


def main() -> None:
    comm = MPI.COMM_WORLD
    scene = load_scene("scenes/rope_on_floor.toml")
    summary = run_scene(scene, OUT / "run", overwrite=True, quiet=True)
    assert summary["status"] == "completed", summary["message"]
    if comm.rank != 0:
        return
    ts = read_series(OUT / "run" / "timeseries.csv")
    delta = scene["contact"]["gap"]
    eps = scene["contact"]["slip_tolerance"]
    assert np.all(ts["min_gap"] > 0.0), "the rope went through the floor"
    assert np.all(ts["friction_dissipation"] >= 0.0)
    assert abs(ts["contact_force_x"][-1] - WEIGHT) < 1e-4 * WEIGHT, ts["contact_force_x"][-1]
    tip = np.stack([ts[f"tip_position_{c}"] for c in "xyz"], axis=1)
    rest = ts["time"] >= 0.8
    creep = np.linalg.norm(tip[rest][-1] - tip[rest][0]) / np.ptp(ts["time"][rest])
    assert creep < eps, creep
    plot(ts, delta)
    print(f"floor's force at rest {ts['contact_force_x'][-1]:.6f} N (weight {WEIGHT:.6f} N), "
          f"smallest gap {ts['min_gap'][1:].min():.3g} m = "
          f"{ts['min_gap'][1:].min() / delta:.3g} delta, creep {creep:.3g} m/s < eps = "
          f"{eps:g} m/s")
    print(f"wrote {OUT}/contact.png and the run folder {OUT}/run")


def plot(ts: dict, delta: float) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = ts["time"]
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    ax[0].plot(t, ts["contact_force_x"] / WEIGHT, label="normal to gravity (x)")
    ax[0].plot(t, ts["contact_force_z"] / WEIGHT, label="along z")
    ax[0].axhline(1.0, color="k", lw=0.6, ls="--")
    ax[0].set(xlabel="t (s)", ylabel="floor's force / weight", ylim=(-0.5, 4),
              title="total contact force")
    ax[0].legend(fontsize=8)
    ax[1].semilogy(t[1:], ts["min_gap"][1:] / delta)
    ax[1].axhline(1.0, color="k", lw=0.6, ls="--")
    ax[1].set(xlabel="t (s)", ylabel="min gap / delta", title="smallest gap (never <= 0)")
    ax[2].semilogy(t[1:], ts["kinetic_energy"][1:] + 1e-16, label="kinetic energy")
    ax[2].semilogy(t[1:], ts["friction_dissipation"][1:] + 1e-16, label="friction's dissipation rate")
    ax[2].set(xlabel="t (s)", title="the rope comes to rest")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "contact.png", dpi=110)


if __name__ == "__main__":
    main()
