"""The stability limit of explicit Euler on a dynamic torsion scene, to warn before a run
that would diverge (docs/stability.md, section (a), where it is derived and measured).

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

from ..integrators.schemes import get_scheme
from ..scenes.schema import Scene

__all__ = ["explicit_stability_warning", "explicit_euler_limit"]


def _kappa_max(n_cells: int, dirichlet_end: bool) -> float:
    theta = (math.pi * (n_cells - 1) / n_cells if dirichlet_end
             else math.pi * (2 * n_cells - 1) / (2 * n_cells))
    return 6.0 * n_cells ** 2 * (1.0 - math.cos(theta)) / (2.0 + math.cos(theta))


def explicit_euler_limit(scene: Scene) -> float | None:
    """The largest stable explicit Euler step of a dynamic torsion scene (0: unstable at
    every step), or None where this estimate does not apply (3-D rod, P2/P3, a
    coefficient varying along s, quasi-static)."""
    mat, geo = scene["material"], scene["geometry"]
    if scene.is_rod_material or geo["degree"] != 1:
        return None
    if not all(mat[k].is_constant for k in ("alpha", "alpha_d", "mu", "mu_d", "nu")):
        return None
    alpha, alpha_d, mu, mu_d, nu = (mat[k].constant for k in
                                    ("alpha", "alpha_d", "mu", "mu_d", "nu"))
    if nu == 0.0:
        return None
    kappa = _kappa_max(geo["n_cells"], scene["boundary"]["end"] == "rotation")
    a, b = mu * kappa / nu, alpha * kappa / nu
    twist = mu / alpha if a * a < 4.0 * b else 4.0 / (a + math.sqrt(a * a - 4.0 * b))
    return min(twist, 2.0 * mu_d / (alpha + alpha_d))


def explicit_stability_warning(scene: Scene) -> str | None:
    """A warning if the scene runs explicit Euler above its stability limit."""
    name = scene["time"]["scheme"]
    if not get_scheme(name).explicit:
        return None
    limit, dt = explicit_euler_limit(scene), scene["time"]["dt"]
    if limit is None or dt <= limit:
        return None
    if limit == 0.0:
        return (f"{scene.source}: [time.scheme]: {name} is unstable at every dt for this "
                "scene (mu = 0 with nu > 0: each undamped twist mode grows by "
                "1 + alpha kappa dt^2/nu per step, docs/stability.md); the run will diverge")
    return (f"{scene.source}: [time.dt]: {dt:g} is above the stability limit {limit:.4g} of "
            f"{name} for this scene (docs/stability.md); the run will diverge")
