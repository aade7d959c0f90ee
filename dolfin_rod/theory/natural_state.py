"""The paper's natural-state assumption (Section 3.3, Assumption ass:natural, eq. natural),
checked numerically on a free energy psi(u_d, v_d, u, v).

The natural strains (u_d, v_d) deserve their name when the contact couple and force
vanish at rest in them, dpsi/du = dpsi/dv = 0 at (u, v) = (u_d, v_d) (eq. natural), and,
for the state to be stable, psi(u_d, v_d, ., .) is minimal there: its Hessian in (u, v)
is positive definite.  ``check_natural_state`` evaluates both for given natural states
with UFL's exact derivatives on constant vectors (UFL folds them to floats), so it
applies to any energy a scene names (``material.energy``) without hand derivatives.  An
energy that carries them (``psi.derivatives(u_d, v_d, u, v)`` -> the same 6-vector and 6x6
matrix in numpy, dna.psi) is checked at a scene's start without UFL, which is imported
only where it evaluates (``dolfin-rod check`` stays free of it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np

__all__ = ["NaturalStateReport", "check_natural_state", "stationarity_and_hessian",
           "start_state_problem"]


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


def stationarity_and_hessian(psi: Callable, u_d, v_d, u=None, v=None,
                             ) -> tuple[np.ndarray, np.ndarray]:
    """(dpsi/d(u, v), d^2psi/d(u, v)^2) at (u, v) (default: u = u_d, v = v_d): a 6-vector
    and a 6x6 matrix."""
    import ufl
    from ufl.algorithms import expand_derivatives

    def constant(a):
        return ufl.as_vector([float(x) for x in a])
    strains = (ufl.variable(constant(u_d if u is None else u)),
               ufl.variable(constant(v_d if v is None else v)))
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


def start_state_problem(psi: Callable, natural: tuple, start: tuple,
                        gradient_tol: float = 1e-8) -> str | None:
    """Why a run cannot start with the energy psi (None if it can): at the natural
    strains ``natural`` = (u_d, v_d) psi is not stationary (eq. natural: a contact force
    or couple at rest, |dpsi/d(u, v)| above ``gradient_tol`` times the largest stiffness
    |eigenvalue|, a strain) or not a minimum (Assumption ass:natural); at the start
    strains ``start`` = (u, v) not convex (a concave energy bends the rod against the
    load); or not finite, or not a scalar.  ``psi.derivatives``, if psi has them (module
    docstring), replace UFL's."""
    by_hand = getattr(psi, "derivatives", None)

    def at(u_d, v_d, u=None, v=None):
        g, h = by_hand(u_d, v_d, u_d if u is None else u, v_d if v is None else v) \
            if by_hand else stationarity_and_hessian(psi, u_d, v_d, u, v)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
            raise ValueError
        return g, np.linalg.eigvalsh(0.5 * (h + h.T))
    where = f"u_d = {list(natural[0])}, v_d = {list(natural[1])}"
    problem = None if by_hand else _not_a_scalar(psi, natural, start)
    if problem:
        return problem
    try:
        g, eig = at(*natural)
        start_eig = eig if tuple(map(tuple, start)) == tuple(map(tuple, natural)) \
            else at(*natural, *start)[1]
    except ValueError:
        return f"psi or its derivatives are not finite at the start ({where})"
    scale = float(np.abs(eig).max())
    if scale == 0.0 or np.abs(g).max() > gradient_tol * scale:
        return (f"the natural state {where} is not stress-free: dpsi/d(u, v) = "
                f"{np.array2string(g, precision=3)} there (eq. natural)")
    for name, values in (("natural state " + where, eig),
                         (f"start state u = {list(start[0])}, v = {list(start[1])}", start_eig)):
        if values.min() <= 0.0:
            return (f"psi is not convex at the {name}: d^2psi/d(u, v)^2 has the eigenvalue "
                    f"{values.min():.3g} (Assumption ass:natural: a minimum)")
    return None


def _not_a_scalar(psi: Callable, natural: tuple, start: tuple) -> str | None:
    """Why psi's value at the start is not a scalar UFL expression (None if it is)."""
    import ufl
    value = psi(*(ufl.as_vector([float(x) for x in a]) for a in (*natural, *start)))
    if not isinstance(value, ufl.core.expr.Expr) or ufl.shape(value) != ():
        return ("psi must return a scalar UFL expression, got shape "
                f"{getattr(value, 'ufl_shape', type(value).__name__)}")
    return None
