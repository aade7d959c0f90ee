"""Synthetic torque-relaxation data of the DNA twist scene (docs/dna.md, "Fitting the
twist relaxation"): scenes/dna_twist_relaxation.toml's half turn Phi0 = pi held at the
bead, the reaction couple about the axis measured.

    ./rodenv python3 examples/fit/make_dna_data.py      # writes dna_twist.csv here
    ./rodenv dolfin-rod fit examples/fit/dna_twist.toml examples/fit/dna_twist.csv --params "material.viscosity.M_d[2]"

The reference is Section 5's torsion closed form (eq. stressrelax,
closed_forms.relaxation) with alpha = C - g^2/S (dna.zero_tension_twist_stiffness),
alpha_d = A_d,33 and mu_d = M_d,33 = TRUE_M_D (1.5 x the scene's 616.5 pN nm^2 s), for
the scene's discrete rod (closed_forms.p1_twist: the P1 twist u0_h and the end
reaction's factor), as tests/test_dna.py checks the scene against it; 51 samples on
[0, 5 s] with seeded Gaussian noise of 1 % of m(0+) = alpha Phi0/L.
"""

from pathlib import Path

import numpy as np

from dolfin_rod import closed_forms, dna

HERE = Path(__file__).resolve().parent
PHI0, LENGTH, N_CELLS = np.pi, 100.0, 16          # scenes/dna_twist_relaxation.toml
TRUE_M_D = 1.5 * 616.5                            # pN nm^2 s; the scene has 616.5
NOISE = 0.01                                      # of m(0+)


def dna_twist_torque(t, m_d: float, n_cells: int = N_CELLS) -> np.ndarray:
    """The reaction couple [pN nm] of the scene's rod with n_cells under Phi0 held."""
    u0_h, factor = closed_forms.p1_twist(PHI0 / LENGTH, LENGTH, n_cells)
    alpha_d = dna.DNA.natural_curvature_ratio * dna.DNA.twist_stiffness
    _, m = closed_forms.relaxation(t, u0_h, dna.zero_tension_twist_stiffness(), alpha_d, m_d)
    return factor * m


def noise_sd() -> float:
    return NOISE * dna.zero_tension_twist_stiffness() * PHI0 / LENGTH


def main() -> None:
    t = np.round(np.arange(0.0, 5.0 + 1e-9, 0.1), 10)
    m = dna_twist_torque(t, TRUE_M_D) + np.random.default_rng(2026).normal(0, noise_sd(), t.size)
    rows = ["time,load,response"] + [f"{a:.4f},{PHI0:.15g},{c:.8f}" for a, c in zip(t, m)]
    (HERE / "dna_twist.csv").write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
