"""What a user gets without options (issue 12, targets 2 and "measure the defaults").

1. Python API, dynamic elastic cantilever of benchmarks/cantilever.py at 32 cells:
   ``RodModel(...)`` and ``TimeStepper(model.problem)`` with every default; set-up of a
   second model + stepper in the process (warm FFCx cache and form cache) and the wall
   time per step over 100 steps of dt = 0.005 (median of 3 runs); the previous default
   (quaternions, generalized-alpha, MUMPS) beside it.
2. ``dolfin-rod run scenes/gravity_cantilever.toml`` (as bundled: 16 cells, 100 steps,
   no option set): its timings.json (set-up, integration, output) per step, with and
   without the ParaView file (rod.bp); pictures off in both.

    ./rodenv python3 benchmarks/defaults.py       writes results/bench/defaults.json
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cantilever as cant  # noqa: E402

from dolfin_rod import TimeStepper  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def api_run(rotations: str, scheme=None, n_cells=32, steps=100, dt=0.005) -> dict:
    t0 = time.perf_counter()
    model = cant.dolfin_rod_model(n_cells, "elastic", rotations=rotations)
    stepper = TimeStepper(model.problem, scheme)
    stepper.compile()
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    stepper.run(0.0, steps * dt, dt)
    wall = time.perf_counter() - t0
    return {"rotations": model.rotations, "method": stepper.description, "setup_s": setup,
            "per_step_ms": 1e3 * wall / stepper.stats.steps,
            "newton_per_step": stepper.stats.newton_iterations / stepper.stats.steps,
            "jacobians_per_step": (stepper.solver.counts["jacobian"] / stepper.stats.steps
                                   if hasattr(stepper, "solver") else None)}


def api(rotations: str, scheme=None) -> dict:
    api_run(rotations, scheme, steps=2)                 # JIT / caches (excluded)
    runs = [api_run(rotations, scheme) for _ in range(3)]
    best = runs[0]
    for key in ("setup_s", "per_step_ms"):
        best[key] = statistics.median(r[key] for r in runs)
        best[f"{key}_runs"] = [r[key] for r in runs]
    return best


def cli(fields: bool) -> dict:
    from dolfin_rod import load_scene, run_scene
    over = {"outputs.plots": False, "outputs.animation": False}
    if not fields:
        over["outputs.fields"] = False
    scene = load_scene(ROOT / "scenes" / "gravity_cantilever.toml", over)
    with tempfile.TemporaryDirectory() as tmp:
        run_scene(scene, Path(tmp) / "warm", quiet=True)           # JIT (excluded)
        summary = run_scene(scene, Path(tmp) / "run", quiet=True)
        timings = json.loads((Path(tmp) / "run" / "timings.json").read_text())
    steps = summary["steps"]
    return {"scene": "gravity_cantilever", "fields": fields, "steps": steps,
            "method": summary["method"], **timings,
            "integration_per_step_ms": 1e3 * timings["integration"] / steps}


def main():
    out = {"api_default": api("auto"),
           "api_previous_default": api("quaternion", "generalized_alpha"),
           "cli": cli(True), "cli_no_fields": cli(False)}
    a, b = out["api_default"], out["api_previous_default"]
    out["per_step_speedup"] = b["per_step_ms"] / a["per_step_ms"]
    for key, row in out.items():
        print(key, json.dumps(row, default=str)[:400])
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "defaults.json").write_text(json.dumps(out, indent=1, default=str))


if __name__ == "__main__":
    main()
