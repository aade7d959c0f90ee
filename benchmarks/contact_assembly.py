"""Cost of self-contact per Newton iteration against the rod's own assembly (issue 26:
broad phase + contact assembly at 1e4 and 1e5 segments).

A rod with self-contact (rod/pair_contact.py) is wound into a tight helix (radius
0.1 m, cells of h = r = 1 cm, the coils 2 r + delta / 2 apart: every segment within
the barrier's reach of the coils above and below it, ~3 pairs per segment) and its
step system (generalized-alpha on the rotation group) assembled at that state:

    rod          the rod's own residual + Jacobian (DOLFINx kernels, the forms)
    broad phase  the pairs within reach (cKDTree on the midpoints + exact closest points)
    pairs        energy, gradient, Hessian of every pair (numpy, vectorised)
    contact      the pair terms added to residual and Jacobian (gather, pairs, insertion)

per Newton iteration (one residual and one Jacobian), best of a few repeats.

    ./rodenv python3 benchmarks/contact_assembly.py [--sizes 10000 100000]
Writes results/bench/contact_assembly.json.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from dolfin_rod import ContactLaw, RodModel, RodParameters, TimeStepper, pair_contact

ROOT = Path(__file__).resolve().parents[1]
R, DELTA, HELIX = 0.01, 0.001, 0.1


def helix_state(model, n_cells):
    """Sets the displacement so the centre line is the tight helix; returns its length."""
    x = model.unknowns.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    pitch = 2 * R + DELTA / 2
    k = 1.0 / np.hypot(HELIX, pitch / (2 * np.pi))          # arc length -> angle
    phi = k * s
    r = np.stack([HELIX * np.cos(phi), HELIX * np.sin(phi), pitch * phi / (2 * np.pi)], 1)
    x.x.array[:] = (r - np.outer(s, (0, 0, 1))).ravel()


def best(f, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def measure(n_cells: int, comm) -> dict:
    length = n_cells * R                                   # h = r
    params = RodParameters(length=length, A=(1.0, 1.0, 1.0), B=(1e3, 1e3, 1e3), density=1.0,
                           section_inertia=1e-4)
    model = RodModel(params, n_cells, model="hyperelastic", start="free", end="free",
                     contact=ContactLaw(R, DELTA, 1e3, self_contact=True), comm=comm)
    model.set_initial_state()
    helix_state(model, n_cells)
    stepper = TimeStepper(model.problem)
    system = stepper.solver.system
    x, b = system.x, system.b.duplicate()
    system.get(0, x)
    terms = system.terms
    contact = model.segment_contact

    def rod_only():
        system.terms = ()
        system.residual(x, b)
        system.jacobian(system.A)
        system.terms = terms

    def with_contact():
        contact.forget()                           # a new state: pairs found anew
        system.residual(x, b)
        system.jacobian(system.A)

    with_contact()                                 # the sparsity grown once
    u = contact.owned_displacement()
    P = contact.line.positions(u)
    pairs = contact.pairs(P)
    X = np.concatenate([P[contact.line.ends[pairs[:, 0]]], P[contact.line.ends[pairs[:, 1]]]], 1)
    weights = np.full(len(pairs), R)
    out = {"segments": n_cells, "pairs": int(len(pairs)), "ranks": comm.size,
           "rod_assembly_s": best(rod_only),
           "broad_phase_s": best(lambda: contact.pairs(P)),
           "pair_terms_s": best(lambda: pair_contact.pair_energy(X, R, DELTA, 1e3, weights)),
           "rod_with_contact_s": best(with_contact)}
    out["contact_s"] = out["rod_with_contact_s"] - out["rod_assembly_s"]
    out["contact_over_rod"] = out["contact_s"] / out["rod_assembly_s"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 100000])
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    results = [measure(n, comm) for n in args.sizes]
    if comm.rank == 0:
        for r in results:
            print(json.dumps(r))
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "contact_assembly.json").write_text(json.dumps(results, indent=1))
        print(f"wrote {folder / 'contact_assembly.json'}")


if __name__ == "__main__":
    main()
