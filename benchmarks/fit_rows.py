"""Benchmark (not a test): the cost of ``dolfin-rod fit`` against the number of data rows
(issue 28 item 29: 1e5 rows took 325 s, 1e6 rows more than 400 s).

The creep example (examples/fit/creep.toml, alpha_d and mu_d fitted) on synthetic data
of N rows on [0, 3] made by the closed form (closed_forms.creep, alpha_d = 1, mu_d = 0.5)
plus 1 % noise; times reading the CSV, one model run and the whole fit.  Writes
results/bench/fit_rows.json.  Run: ./rodenv python3 benchmarks/fit_rows.py
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from dolfin_rod import closed_forms, fit_scene, load_scene, prepare_fit, read_series, versions

ROOT = Path(__file__).resolve().parents[1]
ROWS = (10**3, 10**4, 10**5, 10**6)


def measure(rows: int, folder: Path) -> dict:
    t = np.linspace(0.0, 3.0, rows)
    u, _ = closed_forms.creep(t, 1.0, 2.0, 1.0, 0.2, 0.5)
    noisy = u + 0.01 * np.random.default_rng(0).standard_normal(rows)
    path = folder / f"creep_{rows}.csv"
    np.savetxt(path, np.c_[t, np.ones_like(t), noisy], delimiter=",",
               header="time,load,response", comments="", fmt="%.10g")
    scene = load_scene(ROOT / "examples" / "fit" / "creep.toml")
    t0 = time.perf_counter()
    data = read_series(path)
    read = time.perf_counter() - t0
    problem = prepare_fit(scene, data, "alpha_d,mu_d")
    t0 = time.perf_counter()
    problem(np.log([2.0, 1.0]))
    one_run = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = fit_scene(scene, data, "alpha_d,mu_d")
    fit = time.perf_counter() - t0
    path.unlink()
    return {"rows": rows, "read_s": read, "model_run_s": one_run, "fit_s": fit,
            "model_runs": result.evaluations, "alpha_d": result.values[0],
            "mu_d": result.values[1]}


def main() -> None:
    out = ROOT / "results" / "bench"
    out.mkdir(parents=True, exist_ok=True)
    rows = [measure(n, out) for n in ROWS]
    for r in rows:
        print(f"{r['rows']:>8} rows: read {r['read_s']:.3f} s, one model run "
              f"{r['model_run_s'] * 1e3:.2f} ms, fit {r['fit_s']:.2f} s ({r['model_runs']} "
              f"runs), alpha_d = {r['alpha_d']:.5f}, mu_d = {r['mu_d']:.5f}")
    (out / "fit_rows.json").write_text(json.dumps({"versions": versions(), "rows": rows},
                                                  indent=1) + "\n")


if __name__ == "__main__":
    main()
