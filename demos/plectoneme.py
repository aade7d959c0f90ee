# # A plectoneme: a twisted rod wraps around itself (self-contact, docs/contact.md)
#
# scenes/plectoneme.toml (PyElastica's plectoneme rod: L = 1 m, r = 25 mm, E = 1 MPa,
# nu = 0.5): a rod clamped at both ends on the axis e_3; the top clamp is lowered by
# 0.3 m (slack) over 2 s and turned about e_3 by 6 turns over 6 s (smooth steps), with
# drag.  Past the twist-buckling threshold the rod bends out into a loop, the loop
# closes on itself and the strands press on each other: without self-contact they
# would pass through each other; with `contact.self = true` the segment pairs' barrier
# (gap delta = r / 10) keeps them apart.
#
# Checks (the run's own time series):
#   - Calugareanu-White: the linking number, fixed by the clamps at Lk = (the top
#     clamp's turns), equals the rod's twist Tw (of its director d_1) plus the writhe Wr
#     of its centre line closed along the axis (rod/linking.py) to 1e-3 at every
#     output.  The identity is exact for the polygon and its ribbon, so it holds to
#     round-off as long as no two segments pass through each other; a pass changes
#     Tw + Wr by 2 at once: the check is that of the contact;
#   - no two non-neighbouring segments ever nearer than 2 r: min_pair_gap > 0 at every
#     step (the step test rejects any step that ends with a gap <= 0 or that crossed);
#   - the plectoneme formed: Wr > 1 at the end, the strands in contact
#     (pair_contact_force > 0).
#
# Run: `./rodenv python3 demos/plectoneme.py` (40 cells, dt = 0.01 s, ~1 min), also under
# `mpirun -n 2`; `--small` (28 cells, dt = 0.025 s, ~20 s) is the test's resolution.
# Output: results/plectoneme/ (the run folder: timeseries.csv with twist and writhe,
# rod.bp with the contact force along the rod, animation.gif, snapshots.png) and
# plectoneme.png.

from __future__ import annotations

import pathlib
import sys

import numpy as np
from mpi4py import MPI

from dolfin_rod import load_scene, run

OUT = pathlib.Path("results/plectoneme")
SMALL = {"geometry.n_cells": 28, "time.dt": 0.025, "outputs.every": 4}


def main() -> None:
    small = "--small" in sys.argv[1:]
    scene = load_scene("scenes/plectoneme.toml", SMALL if small else None)
    result = run(scene, out=OUT / "run", overwrite=True, quiet=True)
    assert result.status == "completed", result.summary["message"]
    if MPI.COMM_WORLD.rank != 0:
        return
    s = {k: np.asarray(v, float) for k, v in result.series.items()}
    turns = scene["boundary"]["end_rotation"].vector()
    lk = np.array([turns(t)[2] for t in s["time"]]) / (2 * np.pi)
    error = np.abs(s["twist"] + s["writhe"] - lk)
    assert error.max() < 1e-3, error.max()
    assert np.all(s["min_pair_gap"] > 0.0), "two segments touched through the barrier"
    assert s["writhe"][-1] > 1.0 and s["pair_contact_force"][-1] > 0.0, s["writhe"][-1]
    plot(s, lk, scene["contact"]["gap"])
    print(f"Lk = Tw + Wr to {error.max():.2g} (Lk = {lk[-1]:g} turns: Tw = "
          f"{s['twist'][-1]:.4f}, Wr = {s['writhe'][-1]:.4f}); smallest pair gap "
          f"{s['min_pair_gap'].min():.3g} m = {s['min_pair_gap'].min() / scene['contact']['gap']:.3g} delta"
          f"; pairs' force at the end {s['pair_contact_force'][-1]:.4g} N")
    print(f"wrote {OUT}/plectoneme.png and the run folder {OUT}/run")


def plot(s: dict, lk: np.ndarray, delta: float) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.8))
    ax[0].plot(s["time"], lk, "k-", lw=3, alpha=0.3, label="Lk (clamp's turns)")
    ax[0].plot(s["time"], s["twist"], label="twist Tw")
    ax[0].plot(s["time"], s["writhe"], label="writhe Wr")
    ax[0].plot(s["time"], s["twist"] + s["writhe"], "k--", label="Tw + Wr")
    ax[0].set(xlabel="t (s)", ylabel="turns", title="Calugareanu-White: Lk = Tw + Wr")
    ax[0].legend()
    ax[1].semilogy(s["time"], s["min_pair_gap"] / delta)
    ax[1].set(xlabel="t (s)", ylabel="smallest pair gap / delta",
              title="self-contact: the strands never touch through")
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT / "plectoneme.png", dpi=120)


if __name__ == "__main__":
    main()
