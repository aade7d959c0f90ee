"""Free energies psi(u_d, v_d, u, v) and their derivatives (Section 4.1, eq. quadenergy).

Derivatives are taken by UFL differentiation, so a user energy needs no hand-written
derivatives.  Strains are material components (the paper's sans-serif u, v).
"""

from __future__ import annotations

from typing import Callable

import ufl


def _quad(a, K):
    return 0.5 * (a * K * a if ufl.shape(a) == () else ufl.dot(a, ufl.dot(K, a)))


def quadratic_energy(A, A_d, B=None, B_d=None, v_ref=None) -> Callable:
    """The paper's quadratic energy (eq. quadenergy), with full SPD tensors allowed:

    psi = 1/2 (u - u_d).A(u - u_d) + 1/2 (v - v_d).B(v - v_d)
          + 1/2 u_d.A_d u_d + 1/2 (v_d - v_ref).B_d (v_d - v_ref),

    v_ref = e_3 by default (the straight, unstretched natural state).  Returns
    psi(u_d, v_d, u, v); v and v_d may be None (torsion, inextensible-unshearable rods).
    """
    def psi(u_d, v_d, u, v):
        energy = _quad(u - u_d, A) + _quad(u_d, A_d)
        if v is not None:
            ref = ufl.as_vector((0, 0, 1)) if v_ref is None else v_ref
            energy += _quad(v - v_d, B) + _quad(v_d - ref, B_d)
        return energy
    return psi


def derivatives(psi: Callable, u_d, v_d, u, v):
    """(psi, dpsi/du, dpsi/dv, dpsi/du_d, dpsi/dv_d) by UFL differentiation."""
    vars_ = [None if a is None else ufl.variable(a) for a in (u_d, v_d, u, v)]
    energy = psi(*vars_)
    d = [None if a is None else ufl.diff(energy, a) for a in vars_]
    return energy, d[2], d[3], d[0], d[1]
