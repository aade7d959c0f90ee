"""The stability limit of explicit Euler on the dynamic torsion model (docs/stability.md,
section (a), where it is derived and measured); scenes/run_warnings.py warns before a
scene's run that would diverge.

P1 twist phi and velocity w, DG0 natural twist u_d, constant coefficients.  With u_d
frozen, a twist mode K v = kappa M v (consistent mass) obeys
nu x'' + mu kappa x' + alpha kappa x = 0, i.e. lambda^2 + a lambda + b = 0 with
a = mu kappa/nu, b = alpha kappa/nu, and |1 + dt lambda| <= 1 needs dt <= mu/alpha while
underdamped (a^2 < 4 b) and dt <= 2/|lambda_-| once overdamped; the limit is that of the
stiffest mode kappa_max.  On a uniform mesh of n cells (h = 1/n) the modes are discrete
sines with kappa(theta) = (6/h^2)(1 - cos theta)/(2 + cos theta), theta = j pi/n for
Dirichlet ends (prescribed end rotation) and (2j - 1) pi/(2n) for a free end.  The
natural twist of a cell relaxes at (alpha + alpha_d)/mu_d: dt <= 2 mu_d/(alpha + alpha_d)
(its coupling to phi moves the limit by O(1/mu_d), measured < 1e-8 at mu_d = 1e8).
"""

from __future__ import annotations

import math

__all__ = ["euler_step_limit"]


def _kappa_max(n_cells: int, dirichlet_end: bool) -> float:
    theta = (math.pi * (n_cells - 1) / n_cells if dirichlet_end
             else math.pi * (2 * n_cells - 1) / (2 * n_cells))
    return 6.0 * n_cells ** 2 * (1.0 - math.cos(theta)) / (2.0 + math.cos(theta))


def euler_step_limit(alpha: float, alpha_d: float, mu: float, mu_d: float, nu: float,
                     n_cells: int, rotation_end: bool) -> float:
    """The largest stable explicit Euler step of dynamic torsion (nu > 0) with constant
    coefficients on n_cells P1 cells (0: unstable at every step); ``rotation_end``: the
    end rotation is prescribed (Dirichlet modes), else the end is free."""
    kappa = _kappa_max(n_cells, rotation_end)
    a, b = mu * kappa / nu, alpha * kappa / nu
    twist = mu / alpha if a * a < 4.0 * b else 4.0 / (a + math.sqrt(a * a - 4.0 * b))
    return min(twist, 2.0 * mu_d / (alpha + alpha_d))
