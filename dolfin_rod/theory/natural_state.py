"""The paper's natural-state assumption (Section 3.3, Assumption ass:natural, eq. natural),
checked numerically on a free energy psi(u_d, v_d, u, v).

The natural strains (u_d, v_d) deserve their name when the contact couple and force
vanish at rest in them, dpsi/du = dpsi/dv = 0 at (u, v) = (u_d, v_d) (eq. natural), and,
for the state to be stable, psi(u_d, v_d, ., .) is minimal there: its Hessian in (u, v)
is positive definite.  ``check_natural_state`` evaluates both for given natural states
with UFL's exact derivatives on constant vectors (UFL folds them to floats), so it
applies to any energy a scene names (``material.energy``) without hand derivatives.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np
import ufl
from ufl.algorithms import expand_derivatives

__all__ = ["NaturalStateReport", "check_natural_state", "stationarity_and_hessian"]


@dataclass(frozen=True)
class NaturalStateReport:
    """Worst values over the checked natural states: the largest |dpsi/d(u, v)| relative
    to ``force_scale`` and the smallest eigenvalue of the 6x6 Hessian d^2psi/d(u, v)^2
    relative to its largest one."""

    max_gradient: float
    min_relative_eigenvalue: float
    n_states: int

    def holds(self, gradient_tol: float = 1e-12) -> bool:
        return self.max_gradient <= gradient_tol and self.min_relative_eigenvalue > 0.0


def _value(expr) -> float:
    """A UFL expression of constants (or a float UFL has folded) as a float."""
    return float(expr) if isinstance(expr, (int, float)) else float(expr(()))


def stationarity_and_hessian(psi: Callable, u_d, v_d) -> tuple[np.ndarray, np.ndarray]:
    """(dpsi/d(u, v), d^2psi/d(u, v)^2) at u = u_d, v = v_d: a 6-vector and a 6x6 matrix."""
    def constant(a):
        return ufl.as_vector([float(x) for x in a])
    strains = (ufl.variable(constant(u_d)), ufl.variable(constant(v_d)))
    energy = psi(constant(u_d), constant(v_d), *strains)
    gradient = [expand_derivatives(ufl.diff(energy, w))[k] for w in strains for k in range(3)]
    hess = np.array([[_value(expand_derivatives(ufl.diff(g, w))[k])
                      for w in strains for k in range(3)] for g in gradient])
    return np.array([_value(g) for g in gradient]), hess


def check_natural_state(psi: Callable, natural_states: Iterable[tuple], force_scale: float = 1.0,
                        ) -> NaturalStateReport:
    """Eq. natural and the minimum of psi at (u, v) = (u_d, v_d) for each (u_d, v_d) given.

    ``force_scale``: a typical contact force/couple in the energy's units, so that the
    gradient is reported relative to it (round-off is ~1e-16 of it).  ValueError if a
    natural state gives a non-finite energy or derivative (outside the energy's domain).
    """
    worst_g, worst_eig, n = 0.0, np.inf, 0
    for u_d, v_d in natural_states:
        g, h = stationarity_and_hessian(psi, u_d, v_d)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
            raise ValueError(f"natural state u_d = {list(u_d)}, v_d = {list(v_d)}: psi or its "
                             "derivatives are not finite there")
        eig = np.linalg.eigvalsh(0.5 * (h + h.T))
        worst_g = max(worst_g, float(np.abs(g).max()) / force_scale)
        worst_eig = min(worst_eig, float(eig.min() / np.abs(eig).max()))
        n += 1
    if n == 0:
        raise ValueError("natural_states must hold at least one (u_d, v_d) pair")
    return NaturalStateReport(worst_g, worst_eig, n)
