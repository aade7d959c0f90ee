"""Warnings about a valid scene before its run: explicit Euler above its stability limit
(torsion/stability.py, docs/stability.md); a [section] not small against the rod's length
(a dimension given in mm instead of m)."""

from __future__ import annotations

from ..integrators.schemes import get_scheme
from ..torsion.stability import euler_step_limit
from .scene import Scene

__all__ = ["explicit_stability_warning", "explicit_euler_limit", "slenderness_warnings"]

COEFFICIENTS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
# a rod's length over its section's largest dimension below which the scene is warned
# of: not a slender body (rod theory needs L/d >~ 10); 1000 times too large a section
# (mm read as m) gives L/d ~ 1e-3 L/d_meant
STOUT = 3.0


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


def _largest_dimension(section: dict) -> float | None:
    """The largest extent of a [section] (m), None without one."""
    shape = section["shape"]
    if shape == "circle":
        return 2.0 * section["radius"]
    if shape == "ellipse":
        return 2.0 * max(section["semi_axes"])
    if shape == "rectangle":
        return float(max(section["sides"]))
    if shape == "tube":
        return 2.0 * section["outer_radius"]
    return None


def slenderness_warnings(scene: Scene) -> list[str]:
    """A warning for each rod whose [section] is not small against its length: L/d <
    STOUT (d the section's largest dimension), e.g. a radius in mm given as m."""
    out = []
    for name, part in ([(None, scene)] if not scene.rods else
                       [(rod.name, rod.scene) for rod in scene.rods]):
        d = _largest_dimension(part["section"]) if part.is_rod_material else None
        length = part["geometry"]["length"]
        if d is not None and length < STOUT * d:
            rod = f" (rod {name})" if name else ""
            out.append(f"{scene.source}: [section]{rod}: the section's largest dimension "
                       f"{d:g} is not small against the rod's length {length:g} (L/d = "
                       f"{length / d:.3g}): rod theory needs a slender body, L/d of 10 or "
                       "more; is a dimension in mm instead of m?")
    return out
