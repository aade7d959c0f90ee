"""Warnings about a valid scene before its run: explicit Euler above its stability limit
(torsion/stability.py, docs/stability.md)."""

from __future__ import annotations

from ..integrators.schemes import get_scheme
from ..torsion.stability import euler_step_limit
from .scene import Scene

__all__ = ["explicit_stability_warning", "explicit_euler_limit"]

COEFFICIENTS = ("alpha", "alpha_d", "mu", "mu_d", "nu")


def explicit_euler_limit(scene: Scene) -> float | None:
    """The largest stable explicit Euler step of a dynamic torsion scene (0: unstable at
    every step), or None where this estimate does not apply (3-D rod, P2/P3, a
    coefficient varying along s, quasi-static)."""
    mat, geo = scene["material"], scene["geometry"]
    if scene.is_rod_material or geo["degree"] != 1:
        return None
    if not all(mat[k].is_constant for k in COEFFICIENTS):
        return None
    alpha, alpha_d, mu, mu_d, nu = (mat[k].constant for k in COEFFICIENTS)
    if nu == 0.0:
        return None
    return euler_step_limit(alpha, alpha_d, mu, mu_d, nu, geo["n_cells"],
                            scene["boundary"]["end"] == "rotation")


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
