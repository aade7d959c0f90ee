"""The cost of the stability check of a quasi-static run (issue 27 item 1,
dolfin_rod/analysis/stability.py): the tangent's assembly, its symmetric part and the
MUMPS LDL^T whose negative pivots are counted, after every step.

Scene: the clamped-free column of tests/test_stability.py (EI = 1, shear/axial 1e5,
hyperelastic, rotation vectors, the default integrator) under a dead axial tip load
ramped to 0.9 P_cr in 20 steps (stable throughout), at 16, 64 and 256 cells.  Timed:
the integration (timings.json "integration": steps, diagnostics, the check,
outputs off) with the check off, on, and on with the lowest eigenvalue
(``lowest_eigenvalue = true``, SLEPc), the minimum of 3 runs, and the check's own
seconds per step (``stability_check_ms_per_step``).

    ./rodenv python3 benchmarks/stability_check.py     results/bench/stability_check.json
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from dolfin_rod import parse_scene, run_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = """
[geometry]
length = 1.0
n_cells = {n}
[material]
model = "hyperelastic"
stiffness = {{ A = [1.0, 1.0, 1.0], B = [1e5, 1e5, 1e5] }}
[loads]
end_force = {{ type = "ramp", value = [0.0, 0.0, {load}], duration = 1.0 }}
[time]
t_end = 1.0
dt = 0.05
[stability]
check = {check}
lowest_eigenvalue = {lowest}
[outputs]
fields = false
animation = false
plots = false
progress = false
"""


def timed(n: int, check: bool, folder: Path, lowest: bool = False) -> tuple[float, float | None]:
    """(integration seconds per step, the check's ms per step) of the best of 3 runs."""
    best, check_ms = math.inf, None
    for _ in range(3):
        scene = parse_scene(SCENE.format(n=n, load=-0.9 * math.pi ** 2 / 4,
                                         check=str(check).lower(), lowest=str(lowest).lower()),
                            default_name="column")
        summary = run_scene(scene, folder, quiet=True, overwrite=True)
        clock = json.loads((folder / "timings.json").read_text())
        if clock["integration"] / summary["steps"] < best:
            best = clock["integration"] / summary["steps"]
            check_ms = summary.get("stability_check_ms_per_step")
    return best, check_ms


def main() -> None:
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in (16, 64, 256):
        on, check_ms = timed(n, True, folder / "stability_run")
        off, _ = timed(n, False, folder / "stability_run")
        both, both_ms = timed(n, True, folder / "stability_run", lowest=True)
        rows.append({"cells": n, "step_ms_with_check": 1e3 * on, "step_ms_without": 1e3 * off,
                     "check_ms_per_step": check_ms, "overhead": on / off - 1,
                     "step_ms_with_lowest_eigenvalue": 1e3 * both,
                     "check_and_eigenvalue_ms_per_step": both_ms})
        print(f"{n:4d} cells: {1e3 * off:7.2f} ms/step without, {1e3 * on:7.2f} with the check "
              f"({check_ms:.2f} ms of it; overhead {100 * (on / off - 1):.0f} %), "
              f"{1e3 * both:7.2f} with the lowest eigenvalue too ({both_ms:.2f} ms)")
    (folder / "stability_check.json").write_text(json.dumps({"rows": rows}, indent=1))
    print(f"wrote {folder / 'stability_check.json'}")


if __name__ == "__main__":
    main()
