"""Cost of self-contact per Newton iteration against the rod's own assembly (issue 26:
broad phase + contact assembly at 1e4 and 1e5 segments).

A rod with self-contact (rod/pair_contact.py) is wound into a tight helix (radius
0.1 m, cells of h = r = 1 cm, the coils 2 r + delta / 2 apart: every segment within
the barrier's reach of the coils above and below it, ~3 pairs per segment) and its
step system (generalized-alpha on the rotation group) assembled at that state:

    rod            the rod's own residual + Jacobian (DOLFINx kernels, the forms)
    contact        what the pair terms add to that (gather, candidate list, pairs'
                   terms, residual rows, Jacobian entries), at a new state near the last
                   one: contact_over_rod is the issue's measure (target <= 2)
    update check   Newton's update shortened so that no pair closes too fast
                   (BoundTerm.limit_step, the line search's pre-check, once per
                   iteration; an update of 0.1 delta per coordinate)
    broad phase    tree: the pairs searched anew (cKDTree on the midpoints, when a node
                   moved beyond the skin); list: the candidate list's pairs filtered
    pairs          energy, gradient, Hessian of every pair (numpy, vectorised)
    first Jacobian the first contact Jacobian: the pairs' entries added to the
                   matrix's pattern (fem/assembly.grow_pattern), once

per Newton iteration (one residual and one Jacobian), best of a few repeats; the
exponents p of cost ~ N^p between the sizes.

    ./rodenv python3 benchmarks/contact_assembly.py [--sizes 10000 100000]
        [--pair-curve smooth]
Writes results/bench/contact_assembly.json (contact_assembly_smooth.json); with smooth
pairs (contact.pair_curve, rod/smooth_pairs.py) ``pair_terms`` includes the curves'
closest points (Newton from the segments').
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


def best(f, repeats=5):
    """The shortest of ``repeats`` runs of f (the machine is shared: the others' load
    only lengthens a run)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def best_pair(f, g, repeats=7):
    """The shortest runs of f and of g, run in turns (so that both see the same load)."""
    times = np.array([[best(f, 1), best(g, 1)] for _ in range(repeats)])
    return times.min(axis=0)


def measure(n_cells: int, comm, pair_curve: str = "segments") -> dict:
    t0 = time.perf_counter()
    length = n_cells * R                                   # h = r
    params = RodParameters(length=length, A=(1.0, 1.0, 1.0), B=(1e3, 1e3, 1e3), density=1.0,
                           section_inertia=1e-4)
    model = RodModel(params, n_cells, model="hyperelastic", start="free", end="free",
                     contact=ContactLaw(R, DELTA, 1e3, self=True, pair_curve=pair_curve),
                     comm=comm)
    model.set_initial_state()
    helix_state(model, n_cells)
    stepper = TimeStepper(model.problem)
    system = stepper.solver.system
    x, b = system.x, system.b.duplicate()
    system.get(0, x)
    terms = system.terms
    contact = model.segment_contact
    set_up = time.perf_counter() - t0

    def rod_only():
        system.terms = ()
        system.residual(x, b)
        system.jacobian(system.A)
        system.terms = terms

    def with_contact():
        contact.forget()                           # a new state near the last one
        system.residual(x, b)
        system.jacobian(system.A)

    def tree_search():
        contact.forget_candidates()                # the nodes moved beyond the skin
        contact.pairs(P)

    first = best(with_contact, 1)                  # the sparsity grown once
    u = contact.owned_displacement()
    P = contact.line.positions(u)
    pairs = contact.pairs(P)
    X = P[contact.line.ends[pairs].reshape(-1, 4)]
    weights = np.full(len(pairs), R)

    def pair_terms():
        if pair_curve == "segments":
            pair_contact.pair_energy(X, R, DELTA, 1e3, weights)
        else:       # the curves' closest points (their search) and the pairs' terms
            contact.forget()
            contact.evaluate(u)
    xa = x.getArray(readonly=True)
    update = np.random.default_rng(0).uniform(-1, 1, len(xa)) * 0.1 * DELTA
    rod, both = best_pair(rod_only, with_contact, 7 if n_cells <= 20000 else 3)
    out = {"segments": n_cells, "pair_curve": pair_curve, "pairs": int(len(pairs)),
           "ranks": comm.size,
           "set_up_s": set_up, "first_jacobian_s": first,
           "rod_assembly_s": rod,
           "broad_phase_tree_s": best(tree_search),
           "broad_phase_list_s": best(lambda: contact.pairs(P)),
           "pair_terms_s": best(pair_terms),
           "update_check_s": best(lambda: terms[0].limit_step(xa, update.copy())),
           "rod_with_contact_s": both}
    out["contact_s"] = out["rod_with_contact_s"] - out["rod_assembly_s"]
    out["contact_over_rod"] = out["contact_s"] / out["rod_assembly_s"]
    out["contact_and_check_over_rod"] = (out["contact_s"] + out["update_check_s"]) / \
        out["rod_assembly_s"]
    return out


def growth(results: list[dict]) -> dict:
    """Exponents p of cost ~ N^p between successive sizes."""
    keys = ("rod_assembly_s", "contact_s", "update_check_s", "broad_phase_tree_s",
            "pair_terms_s", "first_jacobian_s")
    out = {}
    for a, b in zip(results, results[1:]):
        ratio = np.log(b["segments"] / a["segments"])
        out[f"{a['segments']}->{b['segments']}"] = {
            k: float(np.log(b[k] / a[k]) / ratio) for k in keys}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 100000])
    parser.add_argument("--pair-curve", choices=("segments", "smooth"), default="segments",
                        help="the pairs' curves (contact.pair_curve)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    results = [measure(n, comm, args.pair_curve) for n in args.sizes]
    if comm.rank == 0:
        for r in results:
            print(json.dumps(r))
        exponents = growth(results)
        print(json.dumps({"growth_exponents": exponents}))
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        name = "contact_assembly" + ("" if args.pair_curve == "segments" else "_smooth")
        (folder / f"{name}.json").write_text(
            json.dumps({"sizes": results, "growth_exponents": exponents}, indent=1))
        print(f"wrote {folder / (name + '.json')}")


if __name__ == "__main__":
    main()
