"""Cost of segment contact with thin obstacles per Newton iteration against the rod's own
assembly (issue 26; rod/obstacle_segments.py, docs/contact.md "Segment contact with thin
obstacles").

A straight rod of N cells (h = 1 cm, r = 2 mm) lies across a bar of radius 3 mm at its
middle (the middle of a cell, at half the barrier's gap: one segment in contact), or
across the top edge of a cube (a 12-triangle mesh turned by 45 degrees, contact =
"segments": its 12 edges are obstacle segments, its faces the nodal law); its step
system (generalized-alpha on the rotation group) is assembled at that state:

    rod            the rod's own residual + Jacobian (the forms; with the cube its nodal
                   law included)
    segments       what the segment term adds (the gathered centre line, every cell's
                   distance to every obstacle segment, the active segments' energy,
                   gradient, Hessian, their rows and entries), at a new state
    evaluate       of that, the distances and the active segments' terms alone (numpy:
                   less noisy on a loaded machine than the difference above)

per Newton iteration (one residual and one Jacobian), best of a few repeats in turns;
the exponents p of cost ~ N^p between the sizes.  ``--obstacle-curve smooth``: the
barrier on the rod's C^1 curve (contact.obstacle_curve).

    ./rodenv python3 benchmarks/obstacle_segments.py [--sizes 1000 10000 100000]
        [--obstacle-curve smooth]
Writes results/bench/obstacle_segments.json (obstacle_segments_smooth.json).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from contact_assembly import best
from dolfin_rod import ContactLaw, Obstacle, RodModel, RodParameters, TimeStepper

ROOT = Path(__file__).resolve().parents[1]
H, R, DELTA, BAR = 0.01, 0.002, 2e-4, 0.003
CUBE = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7),
        (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def obstacle(kind: str, middle: float) -> Obstacle:
    """The bar across the rod's middle, or the cube's top edge under it (gap delta / 2)."""
    if kind == "bar":
        return Obstacle("cylinder", centre=(-(R + 0.5 * DELTA + BAR), 0.0, middle),
                        axis=(0.0, 1.0, 0.0), radius=BAR, length=0.1)
    side = 0.02
    return Obstacle("mesh", vertices=[(x, y, z) for x in (-side, side) for y in (-side, side)
                                      for z in (-side, side)], triangles=CUBE,
                    centre=(-(R + 0.5 * DELTA) - side * np.sqrt(2), 0.0, middle),
                    rotation=(0.0, np.pi / 4, 0.0), contact="segments")


def measure(n_cells: int, kind: str, comm, curve: str = "segments") -> dict:
    n_cells += 1 - n_cells % 2                     # odd: the middle is a cell's middle
    length = n_cells * H
    params = RodParameters(length=length, A=(1.0, 1.0, 1.0), B=(1e3, 1e3, 1e3), density=1.0,
                           section_inertia=1e-4)
    model = RodModel(params, n_cells, model="hyperelastic", start="free",
                     end="free", obstacles=[obstacle(kind, 0.5 * length)],
                     contact=ContactLaw(R, DELTA, 1e3, obstacle_curve=curve), comm=comm)
    model.set_initial_state()
    stepper = TimeStepper(model.problem)
    system = stepper.solver.system
    x, b = system.x, system.b.duplicate()
    system.get(0, x)
    terms = system.terms
    segments = model.obstacle_segments
    others = tuple(t for t in terms if t.contact is not segments)

    def rod_only():
        system.terms = others
        system.residual(x, b)
        system.jacobian(system.A)
        system.terms = terms

    def with_segments():
        segments.forget()                          # a new state
        system.residual(x, b)
        system.jacobian(system.A)

    with_segments()
    times = np.array([[best(rod_only, 1), best(with_segments, 1)] for _ in range(5)])
    rod, both = times.min(axis=0)
    u = segments.owned_displacement()
    active = len(segments.evaluate(u).pairs)

    def evaluate():
        segments.forget()
        segments.evaluate(u)

    out = {"cells": n_cells, "obstacle": kind, "obstacle_curve": curve,
           "obstacle_segments": int(len(segments.index)), "active": active,
           "ranks": comm.size, "rod_assembly_s": float(rod),
           "rod_with_segments_s": float(both), "evaluate_s": best(evaluate)}
    out["segments_s"] = out["rod_with_segments_s"] - out["rod_assembly_s"]
    out["segments_over_rod"] = out["segments_s"] / out["rod_assembly_s"]
    return out


def growth_exponents(results: list, group: str, keys) -> dict:
    """The exponents p of cost ~ cells^p of ``keys`` between consecutive sizes of the
    results with the same ``group``."""
    growth = {}
    for a, b in zip(results, results[1:]):
        if a[group] == b[group]:
            ratio = np.log(b["cells"] / a["cells"])
            growth[f"{a[group]} {a['cells']}->{b['cells']}"] = {
                k: float(np.log(b[k] / a[k]) / ratio) for k in keys}
    return growth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000])
    parser.add_argument("--obstacle-curve", choices=("segments", "smooth"),
                        default="segments")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    results = [measure(n, kind, comm, args.obstacle_curve) for kind in ("bar", "cube")
               for n in args.sizes]
    if comm.rank == 0:
        for r in results:
            print(json.dumps(r))
        growth = growth_exponents(results, "obstacle", ("rod_assembly_s", "evaluate_s"))
        print(json.dumps({"growth_exponents": growth}))
        folder = ROOT / "results" / "bench"
        folder.mkdir(parents=True, exist_ok=True)
        name = "obstacle_segments" + ("_smooth" if args.obstacle_curve == "smooth" else "")
        (folder / f"{name}.json").write_text(
            json.dumps({"sizes": results, "growth_exponents": growth}, indent=1))
        print(f"wrote {folder / f'{name}.json'}")


if __name__ == "__main__":
    main()
