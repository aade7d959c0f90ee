"""The example data of docs/fitting.md: synthetic measurements from the closed forms of
Section 5 (closed_forms.py) with known parameters and seeded Gaussian noise.

    ./rodenv python3 examples/fit/make_data.py      # writes creep.csv, relaxation.csv here

creep.csv       step end torsion m0 = 1 (load), end rotation (response): eq. creepform
                with alpha = 2, alpha_d = 1, mu = 0.2, mu_d = 0.5, noise sd 0.01
relaxation.csv  step end rotation u0 = 0.5 (load), end torsion (response): eq.
                stressrelax with alpha = 2, alpha_d = 1, mu_d = 0.5, noise sd 0.01
"""

from pathlib import Path

import numpy as np

from dolfin_rod import closed_forms

HERE = Path(__file__).resolve().parent
TRUE = {"alpha": 2.0, "alpha_d": 1.0, "mu": 0.2, "mu_d": 0.5}
NOISE = 0.01


def write(path: Path, t, load, response) -> None:
    rows = ["time,load,response"] + [f"{a:.4f},{b:.6g},{c:.8f}" for a, b, c in
                                      zip(t, load, response)]
    path.write_text("\n".join(rows) + "\n")


def main() -> None:
    rng = np.random.default_rng(2026)
    t = np.round(np.arange(0.0, 3.0 + 1e-9, 0.05), 10)
    u, _ = closed_forms.creep(t, 1.0, TRUE["alpha"], TRUE["alpha_d"], TRUE["mu"], TRUE["mu_d"])
    write(HERE / "creep.csv", t, np.ones_like(t), u + rng.normal(0.0, NOISE, t.size))
    _, m = closed_forms.relaxation(t, 0.5, TRUE["alpha"], TRUE["alpha_d"], TRUE["mu_d"])
    write(HERE / "relaxation.csv", t, np.full_like(t, 0.5), m + rng.normal(0.0, NOISE, t.size))


if __name__ == "__main__":
    main()
