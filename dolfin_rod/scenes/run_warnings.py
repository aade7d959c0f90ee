"""Warnings about a valid scene before its run: explicit Euler above its stability limit
(torsion/stability.py, docs/stability.md); a [section] not small against the rod's length
(a dimension given in mm instead of m); a given Newton tolerance time.atol not small
against the scene's forces (a thin fibre in SI units: Newton accepts its first guess); a
load or end motion that starts only at or after time.t_end; a closed rod whose
stress-free curvature is not the circle it starts as."""

from __future__ import annotations

import numpy as np

from ..checks import sample_points
from ..integrators.schemes import get_scheme
from ..torsion.stability import euler_step_limit
from .scene import Scene

__all__ = ["explicit_stability_warning", "explicit_euler_limit", "slenderness_warnings",
           "tolerance_warning", "residual_scale", "late_history_warnings",
           "ring_curvature_warning"]

COEFFICIENTS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
# a rod's length over its section's largest dimension below which the scene is warned
# of: not a slender body (rod theory needs L/d >~ 10); 1000 times too large a section
# (mm read as m) gives L/d ~ 1e-3 L/d_meant
STOUT = 3.0
# time.atol above this fraction of the residual's scale (the largest load) is warned of:
# Newton's absolute test then passes a step's first guess unchanged (measured: a fibre's
# end couple of 1e-9 N m with atol 1e-10 did not creep, or crept linearly, 30 % off)
ATOL_FRACTION = 1e-6


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


def ring_curvature_warning(scene: Scene) -> str | None:
    """A closed rod (rod/ring.py) starts as the circle bending towards d1: curvature
    2 pi / L about d2.  A warning if its reference (stress-free) curvature bends about
    d1, or about d2 the other way: its stress-free ring is then the start turned about
    the tangents (a quarter turn, or inside out), far from the start for Newton."""
    geo = scene["geometry"]
    if not geo.get("closed") or not scene.is_rod_material:
        return None
    u1, u2 = (float(u) for u in geo["reference_curvature"][:2])
    if u1 == 0.0 and u2 >= 0.0:
        return None
    circle = 2 * np.pi / geo["length"]
    return (f"{scene.source}: [geometry.reference_curvature]: a closed rod starts as the "
            f"circle bending towards d1, its curvature {circle:.6g} about d2 (its "
            f"stress-free ring: [0, {circle:.6g}, twist]); [{u1:g}, {u2:g}, ...] bends "
            f"{'about d1' if u1 else 'the other way'}, a ring turned about its tangents "
            "from the start: Newton may not reach the equilibrium from it (a quasi-static "
            "start fails: DIVERGED_DTOL)")


def _peak(spec) -> float:
    """The largest magnitude of a load history's value (over a table's values)."""
    values = spec.values if spec.type == "table" else (spec.value,)
    return max(float(np.linalg.norm(np.atleast_1d(np.asarray(v, float)))) for v in values)


def residual_scale(scene: Scene) -> float:
    """The scale of a 3-D rod's residual (nodal forces and couples, in the scene's
    units): the largest end or point load, distributed load (or weight) times the
    length, or stiffness times a prescribed end motion's strain; 0 without any."""
    scale = 0.0
    for part in [scene] if not scene.rods else [rod.scene for rod in scene.rods]:
        lds, bnd, mat = part["loads"], part["boundary"], part["material"]
        length = part["geometry"]["length"]
        for key in ("end_force", "end_couple", "start_force", "start_couple", "point_force",
                    "point_couple"):
            if lds[key] is not None:
                scale = max(scale, _peak(lds[key]))
        for key in ("distributed_force", "distributed_couple"):
            spec = lds[key]
            if spec is not None:
                shape = 1.0 if spec.profile is None else float(
                    np.max(np.abs(spec.profile.values(sample_points(length)))))
                scale = max(scale, _peak(spec) * shape * length)
        if lds["muscle"] is not None:       # a B-spline lies within its control values
            scale = max(scale, float(np.max(np.abs(lds["muscle"]["amplitude"]))))
        if lds["gravity"] is not None and mat["density"] is not None:
            weight = np.max(np.abs(mat["density"].values(sample_points(length))))
            scale = max(scale, float(np.linalg.norm(lds["gravity"])) * weight * length)
        stiff = mat["stiffness"] or {}
        for motion, tensor in (("rotation", "A"), ("displacement", "B")):
            for end in ("start", "end"):
                spec = bnd[f"{end}_{motion}"]
                if spec is not None and tensor in stiff:
                    k = float(np.max(np.abs(stiff[tensor].terms[0])))
                    scale = max(scale, k * _peak(spec) / length)
    return scale


def tolerance_warning(scene: Scene) -> str | None:
    """A warning if a given time.atol is not small against the 3-D rod's residual_scale,
    for a rod whose state moves at fixed loads (natural strains evolving, viscosity,
    inertia): there a step's first guess can be within atol of the residual's zero (not
    given, atol follows the rod's forces: rod/force_scale.py).  A quasi-static
    elastic rod is not warned of: each load step changes its residual by the load's
    increment, and Newton converges quadratically from there (measured: a 1e-6 N tip
    force on a 0.5 mm steel wire, atol 1e-10, 1e-12, 1e-14: the same deflection)."""
    if not scene.is_rod_material or "atol" not in scene.given["time"]:
        return None
    mat = scene["material"]
    if mat["model"] == "hyperelastic" and not mat["dynamic"]:
        return None
    atol, scale = scene["time"]["atol"], residual_scale(scene)
    if scale == 0.0 or atol <= ATOL_FRACTION * scale:
        return None
    return (f"{scene.source}: [time.atol]: {atol:g} is not small against the scene's forces "
            f"(largest load, or stiffness times a prescribed strain: {scale:.3g}): Newton's "
            "absolute test may pass a step's first guess unchanged (a creep that does not "
            f"creep); take time.atol <= {ATOL_FRACTION * scale:.3g}, or leave it out (Newton's "
            "tolerance then follows the scene's forces; docs/scenes.md, [time])")


def _first_change(spec) -> tuple[float, str] | None:
    """When a history first departs from its value at t = 0, and the key that sets it
    (None if it never changes: a constant, a zero step or ramp)."""
    if spec.type == "table":
        values = np.asarray(spec.values, dtype=float).reshape(len(spec.times), -1)
        moves = np.flatnonzero(np.any(np.diff(values, axis=0) != 0.0, axis=1))
        return (float(spec.times[moves[0]]), "times") if moves.size else None
    if spec.type == "constant" or not np.any(np.asarray(spec.value, dtype=float)):
        return None
    return spec.t0, "t0"


def late_history_warnings(scene: Scene) -> list[str]:
    """A warning for each load or prescribed end motion that first changes at or after
    time.t_end: it never acts in the run (a t0 meant for a longer run)."""
    t_end, out = scene["time"]["t_end"], []
    parts = [(rod.name, rod.scene) for rod in scene.rods] or [(None, scene)]
    for name, part in parts:
        for table in ("loads", "boundary"):
            for key, spec in part[table].items():
                if not hasattr(spec, "breakpoints"):
                    continue
                first = _first_change(spec)
                if first is not None and first[0] >= t_end:
                    rod = f" (rod {name})" if name else ""
                    out.append(f"{scene.source}: [{table}.{key}.{first[1]}]{rod}: it first "
                               f"changes at t = {first[0]:g}, not before time.t_end = "
                               f"{t_end:g}: it never acts in this run")
    return out
