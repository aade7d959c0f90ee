"""Double-stranded DNA as a special Cosserat rod with an evolving natural stretch: the
paper's motivation (Section 1.1), its overstretching transition and its twist relaxation
(issue 16; docs/dna.md).  Units: pN, nm, s (energies pN nm, psi per length in pN).

The free energy (a non-quadratic psi(u_d, v_d, u, v), the general path of Section 4.1)
is written in the elastic strains u_e = u - u_d, v_e = v - v_d (eqs. ustraindecomp,
vstraindecomp; e = v_3 - v_d,3 the elastic stretch, w = u_3 - u_d,3 the elastic twist):

    psi = EI/2 (u_e1^2 + u_e2^2) + GA/2 (v_e1^2 + v_e2^2)                   bending, shear
        + C/2 w^2 + g w e - S lam^2/2 ln(1 - (e/lam)^2)        twist, coupling, stretch
        + 1/2 u_d.A_d u_d + B_ds/2 (v_d1^2 + v_d2^2) + phi(v_d,3)           natural part

* Stretch limiting: n_3 = dpsi/dv_3 = S e / (1 - (e/lam)^2) + g w grows without bound as
  e -> lam (the authors' stretch-limiting rods, RAJROD22A); S is the stretch modulus.
* Twist-stretch coupling g < 0: at zero torque w = -g e / C > 0, DNA overwinds when
  stretched.  The elastic part is convex (S C > g^2), minimal at u_e = v_e = 0: the
  natural-state assumption (eq. natural; natural_state.py checks it).
* The overstretching landscape phi(x), x = v_d,3, has the natural tension
      f(x) = phi'(x) = F_p tanh((x - 1)/sig) + k_p (x - 1) / (1 - ((x - 1)/lam_d)^2),
  sig = F_p / B_d0: stiff (B_d0) below the plateau force F_p, a plateau of slope ~k_p from
  x ~ 1.05 to ~1.7, and a natural stretch limit 1 + lam_d.  f increases monotonically, so
  phi is convex and the equilibrium curve is unique: every hysteresis is rate dependent
  (a double well would add a rate-independent loop, a different effect).

With the local law (eq. dotmfvpeq), N_d,33 dv_d,3/dt = -dpsi/dv_d,3 = n_3 - f(v_d,3): under
a tension n_3 > F_p the natural stretch flows from 1 towards ~1.7 at a rate set by N_d.

Parameter values and their sources are in ``DnaParameters`` (docs/dna.md has the table).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

__all__ = ["DnaParameters", "DNA", "psi", "elastic_tension", "natural_tension",
           "equilibrium_stretch", "zero_tension_twist_stiffness"]


@dataclass(frozen=True)
class DnaParameters:
    """Literature-typical dsDNA values (pN, nm; ~150 mM NaCl, 298 K)."""

    kT: float = 4.11                     # pN nm: k_B T at 298 K
    bending_persistence: float = 50.0    # nm: P (Wang et al. 1997; Bustamante et al. 1994)
    twist_persistence: float = 100.0     # nm: C/kT (Moroz & Nelson 1997; Bryant et al. 2003)
    stretch_modulus: float = 1500.0      # pN: S, the instantaneous modulus (measured 1000-1500:
    #                                      Wang et al. 1997, Gore et al. 2006); slow pulls see
    #                                      (1/S + 1/B_d0)^-1 = 1091 pN, Wang et al.'s 1100
    twist_stretch_coupling: float = -90.0  # pN nm: g (Gore et al. 2006, Lionnet et al. 2006)
    shear_stiffness: float = 500.0       # pN: GA ~ S/3 (isotropic, Poisson 1/2; not measured,
    #                                      it does not enter the straight states computed)
    stretch_limit: float = 0.2           # lam: elastic stretch bound (modelling choice: the
    #                                      law stays within 3% of n = S e up to 50 pN)
    plateau_force: float = 65.0          # pN: F_p (Smith et al. 1996; Cluzel et al. 1996)
    natural_stiffness: float = 4000.0    # pN: B_d0, the B form's slow creep below F_p (above)
    plateau_slope: float = 5.0           # pN: k_p, the plateau rises ~15 pN by 1.7 L0 (Smith
    #                                      et al. 1996; van Mameren et al. 2009)
    natural_stretch_limit: float = 0.8   # lam_d: overstretched length <= 1.8 L0 (Smith 1996)
    natural_curvature_ratio: float = 0.5  # A_d = ratio (EI, EI, C) (illustrative)

    @property
    def bending_stiffness(self) -> float:
        """EI = P kT [pN nm^2]."""
        return self.bending_persistence * self.kT

    @property
    def twist_stiffness(self) -> float:
        """C = C_p kT [pN nm^2]."""
        return self.twist_persistence * self.kT

    def energy(self, u_d, v_d, u, v):
        """psi(u_d, v_d, u, v) per length [pN] (module docstring); UFL vectors, or
        constant vectors (then a float).  (UFL is imported here: checking a scene that
        names this energy stays free of it.)"""
        import ufl
        EI, C, g = self.bending_stiffness, self.twist_stiffness, self.twist_stretch_coupling
        S, lam, GA = self.stretch_modulus, self.stretch_limit, self.shear_stiffness
        ue, ve = u - u_d, v - v_d
        e, w = ve[2], ue[2]
        elastic = (0.5 * EI * (ue[0] ** 2 + ue[1] ** 2) + 0.5 * GA * (ve[0] ** 2 + ve[1] ** 2)
                   + 0.5 * C * w ** 2 + g * w * e
                   - 0.5 * S * lam ** 2 * ufl.ln(1 - (e / lam) ** 2))
        a = self.natural_curvature_ratio
        natural = (0.5 * a * (EI * (u_d[0] ** 2 + u_d[1] ** 2) + C * u_d[2] ** 2)
                   + 0.5 * a * GA * (v_d[0] ** 2 + v_d[1] ** 2) + self.landscape(v_d[2]))
        return elastic + natural

    def strain_derivatives(self, u_d, v_d, u, v) -> tuple[np.ndarray, np.ndarray]:
        """(dpsi/d(u, v), d^2psi/d(u, v)^2) at constant strains by hand (numpy): what
        natural_state.stationarity_and_hessian gives by UFL, so that checking a scene
        with this energy needs no UFL.  Only the elastic part depends on (u, v)."""
        EI, C, g = self.bending_stiffness, self.twist_stiffness, self.twist_stretch_coupling
        S, lam, GA = self.stretch_modulus, self.stretch_limit, self.shear_stiffness
        ue = np.asarray(u, dtype=float) - np.asarray(u_d, dtype=float)
        ve = np.asarray(v, dtype=float) - np.asarray(v_d, dtype=float)
        e, w = ve[2], ue[2]
        r = 1 - (e / lam) ** 2
        gradient = np.array([EI * ue[0], EI * ue[1], C * w + g * e,
                             GA * ve[0], GA * ve[1], g * w + S * e / r])
        hessian = np.diag([EI, EI, C, GA, GA, S * (1 + (e / lam) ** 2) / r ** 2])
        hessian[2, 5] = hessian[5, 2] = g
        return gradient, hessian

    def landscape(self, x):
        """phi(x), x = v_d,3: the natural-stretch energy whose derivative is f(x)."""
        import ufl
        F_p, k_p, lam_d = self.plateau_force, self.plateau_slope, self.natural_stretch_limit
        sig = F_p / self.natural_stiffness
        y = x - 1
        return (F_p * sig * ufl.ln(ufl.cosh(y / sig))
                - 0.5 * k_p * lam_d ** 2 * ufl.ln(1 - (y / lam_d) ** 2))

    def linearised(self) -> dict[str, list[float]]:
        """Diagonals of the Hessians at the unstressed state (u_d = u = 0, v_d = v = e_3):
        A, B of psi in (u, v), A_d, B_d of its natural part in (u_d, v_d), as a scene's
        material.stiffness writes them."""
        EI, C, GA = self.bending_stiffness, self.twist_stiffness, self.shear_stiffness
        a = self.natural_curvature_ratio
        return {"A": [EI, EI, C], "B": [GA, GA, self.stretch_modulus],
                "A_d": [a * EI, a * EI, a * C],
                "B_d": [a * GA, a * GA, self.natural_stiffness + self.plateau_slope]}


DNA = DnaParameters()


def psi(u_d, v_d, u, v):
    """The scene entry point ``material.energy = "dolfin_rod.dna:psi"``: DNA's energy."""
    return DNA.energy(u_d, v_d, u, v)


# the scene check's derivatives without UFL (natural_state.start_state_problem)
psi.derivatives = DNA.strain_derivatives


# --- the homogeneous straight states (hand derivatives of psi, tests compare with UFL's) ----


def natural_tension(x, p: DnaParameters = DNA):
    """f(x) = d phi / dx [pN], x = v_d,3 (numpy, vectorised)."""
    F_p, k_p, lam_d = p.plateau_force, p.plateau_slope, p.natural_stretch_limit
    y = np.asarray(x, dtype=float) - 1
    return F_p * np.tanh(y * p.natural_stiffness / F_p) + k_p * y / (1 - (y / lam_d) ** 2)


def elastic_tension(e, p: DnaParameters = DNA):
    """n_3 [pN] at elastic stretch e and zero torque (m_3 = C w + g e = 0, w = -g e / C):
    n_3 = S e / (1 - (e/lam)^2) - g^2 e / C."""
    e = np.asarray(e, dtype=float)
    g, lam = p.twist_stretch_coupling, p.stretch_limit
    return p.stretch_modulus * e / (1 - (e / lam) ** 2) - g ** 2 * e / p.twist_stiffness


def equilibrium_stretch(force: float, p: DnaParameters = DNA) -> tuple[float, float]:
    """(v_d,3, v_3) at rest under the end tension ``force`` with a torque-free end:
    dpsi/dv_d,3 = 0, i.e. f(v_d,3) = n_3 = force, and v_3 = v_d,3 + e(force)."""
    lam, lam_d = p.stretch_limit, p.natural_stretch_limit
    edge = 1 - 1e-12
    x = brentq(lambda z: natural_tension(z, p) - force, 1 - edge * lam_d, 1 + edge * lam_d,
               xtol=1e-15, rtol=1e-15)
    e = brentq(lambda z: elastic_tension(z, p) - force, -edge * lam, edge * lam,
               xtol=1e-15, rtol=1e-15)
    return x, x + e


def zero_tension_twist_stiffness(p: DnaParameters = DNA) -> float:
    """dm_3/dw at n_3 = 0 and w = 0: C - g^2/S [pN nm^2] (the stretch relaxes the twist)."""
    return p.twist_stiffness - p.twist_stretch_coupling ** 2 / p.stretch_modulus
