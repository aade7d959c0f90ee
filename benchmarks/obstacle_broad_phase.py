"""The broad phase of segment contact with a mesh's sharp edges per Newton iteration
against the rod's own assembly, and comparing every pair as before it (issue 26;
rod/obstacle_segments.py, docs/contact.md "Cost of segment contact").

A straight rod of N cells (h = 1 cm, r = 2 mm, delta = 0.2 mm) lies on k cubes of side
4 cm turned by 45 degrees about e_2 (tests/meshes.boxes, one mesh, contact =
"segments": its 12 k sharp edges are obstacle segments, its faces the nodal law), one
cube's top edge under the middle of a cell every N / k cells at half the barrier's gap
(k active pairs).  Its step system (generalized-alpha on the rotation group) is assembled
at that state, per Newton iteration (one residual and one Jacobian), best of a few
repeats in turns:

    rod_forms        the rod's own forms (its nodal law of the mesh included, the
                     nodes' features as located last)
    features         locating the nodes' closest features of the mesh (the nodal law's
                     broad and narrow phase, rod/triangle_mesh.py)
    segments         what the segment term adds (the gathered centre line, the broad
                     phase's candidate list checked, the candidates' distances, the
                     active segments' energy, gradient, Hessian, rows and entries), at a
                     new state near the last one (the list kept: a Newton iteration)
    evaluate         of that, the distances and the active segments' terms alone
                     (numpy: less noisy than the difference above); ``evaluate_all_s``
                     the same comparing every pair (as before the broad phase; measured
                     up to ``--all-pairs`` pairs, beyond it the cost per pair measured
                     at the largest size times N 12 k)
    search           the broad phase anew (the cells' midpoint tree searched against the
                     edges' pieces; only when a node moved beyond the skin r / 2)

and the exponents p of cost ~ N^p between the sizes.

    ./rodenv python3 benchmarks/obstacle_broad_phase.py [--sizes 1000 10000 100000]
Writes results/bench/obstacle_broad_phase.json.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from contact_assembly import best
from obstacle_segments import growth_exponents
from dolfin_rod import ContactLaw, Obstacle, RodModel, RodParameters, TimeStepper

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from meshes import boxes  # noqa: E402

H, R, DELTA, SIDE = 0.01, 0.002, 2e-4, 0.02


def cubes(n_cells: int, count: int) -> Obstacle:
    """``count`` cubes turned by 45 degrees along the rod, a top edge (along e_2) under
    the middle of a cell every n_cells / count cells, delta / 2 below the rod's surface."""
    cells = (np.arange(count) + 0.5) * n_cells // count
    centres = np.column_stack([np.full(count, -(R + 0.5 * DELTA) - SIDE * np.sqrt(2)),
                               np.zeros(count), (cells + 0.5) * H])
    V, T = boxes(centres, SIDE, np.pi / 4)
    return Obstacle("mesh", vertices=V, triangles=T, contact="segments")


def measure(n_cells: int, count: int, comm, all_pairs: int) -> dict:
    params = RodParameters(length=n_cells * H, A=(1.0, 1.0, 1.0), B=(1e3, 1e3, 1e3),
                           density=1.0, section_inertia=1e-4)
    model = RodModel(params, n_cells, model="hyperelastic", start="free", end="free",
                     obstacles=[cubes(n_cells, count)], contact=ContactLaw(R, DELTA, 1e3),
                     comm=comm)
    model.set_initial_state()
    system = TimeStepper(model.problem).solver.system
    x, b = system.x, system.b.duplicate()
    system.get(0, x)
    segments = model.obstacle_segments
    terms = system.terms
    rod = tuple(t for t in terms if t.contact is not segments)
    forms = tuple(t for t in rod if not hasattr(t, "prepare"))

    def assemble(which):
        def run():
            segments.forget()                      # a new state (the list kept)
            system.terms = which
            system.residual(x, b)
            system.jacobian(system.A)
            system.terms = terms
        return run

    assemble(terms)()
    repeats = 5 if n_cells < 100_000 else 3
    times = np.array([[best(assemble(w), 1) for w in (forms, rod, terms)]
                      for _ in range(repeats)]).min(axis=0)
    u = segments.owned_displacement()

    def evaluate():
        segments.forget()
        segments.evaluate(u)

    def search():
        segments.forget_candidates()
        evaluate()

    pairs = n_cells * len(segments.index)
    out = {"cells": n_cells, "cubes": count, "sharp_edges": int(len(segments.index)),
           "active": len(segments.evaluate(u).pairs), "ranks": comm.size,
           "rod_forms_s": float(times[0]), "features_s": float(times[1] - times[0]),
           "segments_s": float(times[2] - times[1]),
           "evaluate_s": best(evaluate, repeats), "search_s": best(search, repeats)}
    out["search_s"] -= out["evaluate_s"]
    if pairs <= all_pairs:
        segments.tree = False
        out["evaluate_all_s"] = best(evaluate, min(repeats, 3))
        segments.tree = True
    out["evaluate_over_rod_forms"] = out["evaluate_s"] / out["rod_forms_s"]
    out["segments_over_rod_forms"] = out["segments_s"] / out["rod_forms_s"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    parser.add_argument("--cubes", type=int, nargs="+", default=[9, 84])
    parser.add_argument("--all-pairs", type=int, default=2_000_000,
                        help="the most pairs compared all (memory: ~0.3 kB a pair)")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    load = os.getloadavg()
    results = []
    for count in args.cubes:
        for n in args.sizes:
            results.append(measure(n, count, comm, args.all_pairs))
            if comm.rank == 0:
                print(json.dumps(results[-1]), flush=True)
    for count in args.cubes:                       # before: every pair, at its cost per pair
        rows = [r for r in results if r["cubes"] == count]
        measured = [r for r in rows if "evaluate_all_s" in r]
        if measured:
            per_pair = measured[-1]["evaluate_all_s"] / (measured[-1]["cells"]
                                                         * measured[-1]["sharp_edges"])
            for r in rows:
                if "evaluate_all_s" not in r:
                    r["evaluate_all_estimated_s"] = per_pair * r["cells"] * r["sharp_edges"]
    growth = growth_exponents(results, "sharp_edges", ("rod_forms_s", "features_s",
                                                       "evaluate_s", "search_s"))
    if comm.rank == 0:
        out = {"load_before": load, "load_after": os.getloadavg(), "sizes": results,
               "growth_exponents": growth}
        print(json.dumps({k: out[k] for k in ("load_before", "load_after",
                                              "growth_exponents")}))
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "obstacle_broad_phase.json").write_text(json.dumps(out, indent=1))
        print(f"wrote {folder / 'obstacle_broad_phase.json'}")


if __name__ == "__main__":
    main()
