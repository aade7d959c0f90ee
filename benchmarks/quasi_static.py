"""Quasi-static rods with every default (issue 12): rotation vectors against the
previous default, quaternions, in one run.

Two scenes on the cantilever of benchmarks/cantilever.py (clamped at s = 0, free at
s = L, no inertia), each at 8 .. 512 cells:

"load steps"  hyperelastic, a dead transverse tip force ramped to 3 E I / L^2 in 10 load
              steps of dt = 0.1 (a tip rotation of ~1.1 rad): a user's load-stepping
              run.  Previous default: TimeStepper's backward Euler on quaternions.
"creep"       the evolving model of cantilever.py (A_d = A, B_d = B, M_d = tau A,
              N_d = tau B, tau = 0.1) under a step tip force of 0.3 E I / L^2 for 1 s in
              steps of dt = 0.02 (50 steps): the natural curvature creeps towards the
              bent shape.  Previous default: a scene's BDF2 on quaternions.

Configurations: "default", ``RodModel(...)`` and ``TimeStepper(model.problem)`` with
nothing set (rotation vectors, generalized-alpha on the rotation group with algebraic
positions and rotations); "rotation vectors, previous scheme" (what a scene that names
the scheme gets now); "previous default" (quaternions and that scheme).  Timed: set-up
(the stepper and its compiled forms, warm caches) and the run from t0 (the start's solve
included) to the last step; the minimum of 3 runs.  The tips of the default and the
previous default are compared at the final time (the same discrete model: equal up to
the time discretisation).

    ./rodenv python3 benchmarks/quasi_static.py [--quick]   results/bench/quasi_static.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cantilever as cant  # noqa: E402

from dolfin_rod import EndLoad, loads, RodModel, RodParameters, TimeStepper  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = cant.SCENES["elastic"]
EI = cant.section_constants(SCENE)[0][0]

CASES = {
    "load steps": dict(evolving=False, force=3.0 * EI, history=loads.ramp(1.0, 1.0),
                       t_end=1.0, dt=0.1, previous="backward_euler"),
    "creep": dict(evolving=True, force=0.3 * EI, history=loads.step(1.0),
                  t_end=1.0, dt=0.02, previous="bdf2"),
}


def model(case: dict, n_cells: int, rotations: str) -> RodModel:
    A, B = cant.section_constants(SCENE)
    extra = dict(A_d=A, B_d=B, M_d=tuple(cant.TAU * a for a in A),
                 N_d=tuple(cant.TAU * b for b in B)) if case["evolving"] else {}
    params = RodParameters(length=cant.L, A=A, B=B, **extra)
    force = EndLoad("force", (-case["force"], 0.0, 0.0), case["history"])
    return RodModel(params, n_cells, model="evolving" if case["evolving"] else "hyperelastic",
                    end_loads=[force], rotations=rotations)


CONFIGS = {                     # (rotations, scheme: None = the default, "previous")
    "default": ("auto", None),
    "rotation vectors, previous scheme": ("rotation_vector", "previous"),
    "previous default": ("quaternion", "previous"),
}


def timed_run(case: dict, n_cells: int, config: str) -> dict:
    rotations, scheme = CONFIGS[config]
    m = model(case, n_cells, rotations)
    m.set_initial_state()
    t0 = time.perf_counter()
    stepper = TimeStepper(m.problem, case["previous"] if scheme else None)
    stepper.compile()
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    stepper.run(0.0, case["t_end"], case["dt"])
    wall = time.perf_counter() - t0
    d = m.diagnostics(case["t_end"])
    return {"rotations": m.rotations, "method": stepper.description, "setup_s": setup,
            "wall_s": wall, "steps": stepper.stats.steps,
            "newton": stepper.stats.newton_iterations,
            "tip": [d[f"tip_position_{c}"] for c in "xyz"]}


def measure(case: dict, n_cells: int, config: str, repeats: int) -> dict:
    timed_run(case, n_cells, config)                       # JIT and caches (excluded)
    runs = [timed_run(case, n_cells, config) for _ in range(repeats)]
    best = min(runs, key=lambda r: r["wall_s"])
    best["wall_s_runs"] = [r["wall_s"] for r in runs]
    best["setup_s"] = min(r["setup_s"] for r in runs)
    return best


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="8 and 32 cells only")
    args = parser.parse_args()
    sizes = (8, 32) if args.quick else (8, 32, 128, 512)
    rows = []
    for name, case in CASES.items():
        for n in sizes:
            row = {"case": name, "n_cells": n}
            row.update({config: measure(case, n, config, 3) for config in CONFIGS})
            old, new = row["previous default"], row["default"]
            tip_scale = np.linalg.norm(np.array(old["tip"]) - [0.0, 0.0, cant.L])
            row["speedup"] = old["wall_s"] / new["wall_s"]
            row["tip_difference"] = float(np.linalg.norm(np.subtract(new["tip"], old["tip"]))
                                          / tip_scale)
            rows.append(row)
            print(f"{name:10s} n = {n:4d}: " + " | ".join(
                f"{c}: {1e3 * row[c]['wall_s']:7.2f} ms ({row[c]['newton']} Newton, set-up "
                f"{1e3 * row[c]['setup_s']:.0f} ms)" for c in CONFIGS)
                + f" | speed-up {row['speedup']:.2f}x, tips differ {row['tip_difference']:.1e}",
                flush=True)
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "quasi_static.json").write_text(json.dumps({"rows": rows}, indent=1))
    print(f"wrote {folder / 'quasi_static.json'}")


if __name__ == "__main__":
    main()
