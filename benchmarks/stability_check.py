"""The cost of the stability check of a quasi-static run (issue 27 item 1,
dolfin_rod/analysis/stability.py): the tangent's assembly, its symmetric part and the
MUMPS LDL^T whose negative pivots are counted, after every step.

Scene: the clamped-free column of tests/test_stability.py (EI = 1, shear/axial 1e5,
hyperelastic, rotation vectors, the default integrator) under a dead axial tip load
ramped to 0.9 P_cr in 20 steps (stable throughout), at 16, 64 and 256 cells.  Timed:
the integration (timings.json "integration": steps, diagnostics, the check,
outputs off) with the check off, on, on without the banded Cholesky test (MUMPS's
LDL^T at every check: ``stability.factorisation = "mumps"``, the check before that
test, the A/B in one run), and on with the lowest eigenvalue
(``lowest_eigenvalue = true``, SLEPc), the minimum of 10 runs, and the check's own
seconds per step (``stability_check_ms_per_step``).  The configurations alternate
within each repeat, so that a change of the machine's load hits them alike.

    ./rodenv python3 benchmarks/stability_check.py     results/bench/stability_check.json
"""

from __future__ import annotations

import json
import math
import os
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
factorisation = "{factorisation}"
[outputs]
fields = false
animation = false
plots = false
progress = false
"""


def run_once(n: int, check: bool, folder: Path, lowest: bool = False,
             banded: bool = True) -> tuple[float, float | None]:
    """(integration seconds per step, the check's ms per step) of one run."""
    scene = parse_scene(SCENE.format(n=n, load=-0.9 * math.pi ** 2 / 4,
                                     check=str(check).lower(), lowest=str(lowest).lower(),
                                     factorisation="banded" if banded else "mumps"),
                        default_name="column")
    summary = run_scene(scene, folder, quiet=True, overwrite=True)
    clock = json.loads((folder / "timings.json").read_text())
    return clock["integration"] / summary["steps"], summary.get("stability_check_ms_per_step")


REPEATS = 10
CONFIGURATIONS = {"without": {"check": False}, "with_check": {"check": True},
                  "with_check_mumps": {"check": True, "banded": False},
                  "with_lowest_eigenvalue": {"check": True, "lowest": True}}


def main() -> None:
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in (16, 64, 256):
        best = {name: (math.inf, None) for name in CONFIGURATIONS}
        for _ in range(REPEATS):
            for name, options in CONFIGURATIONS.items():
                best[name] = min(best[name], run_once(n, folder=folder / "stability_run",
                                                      **options), key=lambda r: r[0])
        off = best["without"][0]
        row = {"cells": n, "load_average": os.getloadavg()[0],
               "step_ms_without": 1e3 * off}
        for name in list(CONFIGURATIONS)[1:]:
            step, check_ms = best[name]
            row[f"step_ms_{name}"] = 1e3 * step
            row[f"check_ms_per_step_{name}"] = check_ms
            row[f"overhead_{name}"] = step / off - 1
        rows.append(row)
        print(f"{n:4d} cells (load {row['load_average']:.1f}): {1e3 * off:6.2f} ms/step without; "
              + "; ".join(f"{name} {row[f'step_ms_{name}']:6.2f} (check "
                          f"{row[f'check_ms_per_step_{name}']:.2f} ms, overhead "
                          f"{100 * row[f'overhead_{name}']:.0f} %)"
                          for name in list(CONFIGURATIONS)[1:]))
    (folder / "stability_check.json").write_text(json.dumps({"rows": rows}, indent=1))
    print(f"wrote {folder / 'stability_check.json'}")


if __name__ == "__main__":
    main()
