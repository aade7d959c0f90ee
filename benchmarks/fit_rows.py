"""Benchmark (not a test): the cost of ``dolfin-rod fit`` against the number of data rows
(issue 28 item 29: 1e5 rows took 325 s, 1e6 rows more than 400 s).

Cases (synthetic data of N rows at times k span / N, the closed form plus 1 % noise, written as CSV):
* ``ode``: the creep example (examples/fit/creep.toml, alpha_d and mu_d fitted) on
  [0, 3], made by closed_forms.creep (alpha_d = 1, mu_d = 0.5); the ODE's exact mode;
* ``torsion_pde``: the same scene with ``scene.model = "torsion"`` (the FE torsion
  model, 8 cells, dt = 0.05): it steps at the scene's dt whatever the rows;
* ``rod``: examples/fit/dna_twist.toml (the 3-D rod, 16 cells) on [0, 5] with the torque
  of examples/fit/make_dna_data.py's closed form: one model run only (a fit is
  benchmarks/setup_cost.py's).
Times reading the CSV, one model run and (ode, torsion_pde) the whole fit.  Prints and
writes results/bench/fit_rows.json.
Run: ./rodenv python3 benchmarks/fit_rows.py [--rows 100000,1000000] [--cases ode,rod] [--no-fit]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from dolfin_rod import closed_forms, fit_scene, load_scene, prepare_fit, read_series, versions

ROOT = Path(__file__).resolve().parents[1]
ROWS = (10**3, 10**4, 10**5, 10**6)
CREEP = ROOT / "examples" / "fit" / "creep.toml"
DNA = ROOT / "examples" / "fit" / "dna_twist.toml"
# case -> (scene file, overrides, data span, parameters, their trial values, fit?)
CASES = {
    "ode": (CREEP, {}, 3.0, "alpha_d,mu_d", [2.0, 1.0], True),
    "torsion_pde": (CREEP, {"scene.model": "torsion"}, 3.0, "alpha_d,mu_d", [2.0, 1.0],
                    True),
    "rod": (DNA, {}, 5.0, "material.viscosity.M_d[2]", [616.5], False),
}


def response(case: str, t: np.ndarray) -> np.ndarray:
    """The synthetic measurement: torsion creep (alpha = 2, alpha_d = 1, mu = 0.2,
    mu_d = 0.5, unit end torsion), or the DNA torque's relaxation to alpha alpha_d /
    (alpha + alpha_d) of its start (a shape only: the model run is timed, not fitted)."""
    if case != "rod":
        return closed_forms.creep(t, 1.0, 2.0, 1.0, 0.2, 0.5)[0]
    return 1.0 + np.exp(-t)


def measure(case: str, rows: int, folder: Path, fit: bool = True) -> dict:
    scene_file, overrides, span, params, trial, whole = CASES[case]
    t = np.arange(rows) * (span / rows)      # a grid k h, as instruments write
    load = np.full_like(t, np.pi if case == "rod" else 1.0)
    noisy = response(case, t) * (1.0 + 0.01 * np.random.default_rng(0).standard_normal(rows))
    path = folder / f"{case}_{rows}.csv"
    np.savetxt(path, np.c_[t, load, noisy], delimiter=",", header="time,load,response",
               comments="", fmt=("%.12g", "%.10g", "%.10g"))
    scene = load_scene(scene_file, overrides)
    t0 = time.perf_counter()
    data = read_series(path)
    out = {"case": case, "rows": rows, "read_s": time.perf_counter() - t0}
    problem = prepare_fit(scene, data, params)
    t0 = time.perf_counter()
    problem(np.log(trial))
    out.update(model=problem.model, model_step=problem.dt,
               model_run_s=time.perf_counter() - t0)
    if whole and fit:
        t0 = time.perf_counter()
        result = fit_scene(scene, data, params)
        out.update(fit_s=time.perf_counter() - t0, model_runs=result.evaluations,
                   values=result.values)
    path.unlink()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", default=",".join(map(str, ROWS)))
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--no-fit", action="store_true", help="one model run only")
    parser.add_argument("--json", default="fit_rows.json", help="file in results/bench")
    args = parser.parse_args()
    out = ROOT / "results" / "bench"
    out.mkdir(parents=True, exist_ok=True)
    rows = [measure(case, int(n), out, not args.no_fit) for case in args.cases.split(",")
            for n in args.rows.split(",")]
    for r in rows:
        fit = (f", fit {r['fit_s']:.2f} s ({r['model_runs']} runs), values "
               f"{', '.join(f'{v:.5g}' for v in r['values'] if v is not None)}"
               if "fit_s" in r else "")
        print(f"{r['case']:>12} {r['rows']:>8} rows: read {r['read_s']:.3f} s, one model "
              f"run ({r['model']}, step {r['model_step']:.3g}) {r['model_run_s']:.3f} s{fit}")
    report = {"versions": versions(), "rows": rows}
    (out / args.json).write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
