"""The contact keys of a rod scene ([contact], [[obstacles]]; docs/contact.md): their
rules across keys and the obstacles and contact law they describe (rod/contact.py)."""

from __future__ import annotations

import numpy as np

from .scene import Scene

# per shape the pose keys it needs (every other pose key is an error)
POSE_KEYS = {"plane": ("point", "normal"), "sphere": ("centre", "radius"),
             "cylinder": ("centre", "axis", "radius", "length")}
DIRECTIONS = ("normal", "axis")


def check_contact_keys(scene: Scene) -> None:
    """[[obstacles]] need contact.radius; [contact] needs obstacles; each obstacle has the
    pose keys of its shape; gap < radius; friction needs a dynamic rod (segment friction
    also its kind of contact)."""
    err, contact, obstacles = scene.error, scene["contact"], scene["obstacles"]
    given = scene.given["contact"]
    if not touching(scene):
        if given:
            raise err(f"contact.{sorted(given)[0]}", "applies to rods with [[obstacles]], "
                                                     "contact.self or contact.between_rods")
        return
    if contact["radius"] is None:
        contact["radius"] = section_radius(scene)
    if contact["radius"] is None:
        raise err("contact.radius", "missing: contact needs the rod's radius (or a "
                                    "circle or tube [section])")
    if contact["gap"] is not None and contact["gap"] >= contact["radius"]:
        raise err("contact.gap", f"must be < contact.radius = {contact['radius']:g} (the "
                                 f"barrier acts within the gap), got {contact['gap']:g}")
    for k, ob in enumerate(obstacles):
        name, needed = f"obstacles[{k}]", POSE_KEYS[ob["shape"]]
        for key in POSE_KEYS["cylinder"] + ("point", "normal"):
            if key in needed and ob[key] is None:
                raise err(f"{name}.{key}", f"missing: a {ob['shape']} needs "
                                           f"{', '.join(needed)}")
            if key not in needed and ob[key] is not None:
                raise err(f"{name}.{key}", f"does not apply to a {ob['shape']} (its keys: "
                                           f"{', '.join(needed)}, friction)")
        for key in DIRECTIONS:
            if ob[key] is not None and not np.linalg.norm(ob[key]) > 0:
                raise err(f"{name}.{key}", "must not be the zero vector")
        if ob["friction"] > 0 and not scene["material"]["dynamic"]:
            raise err(f"{name}.friction", "friction depends on the velocity: it needs a "
                                          "dynamic rod (material.density > 0)")
    for key, pairs in (("self_friction", "self"), ("between_rods_friction", "between_rods")):
        if contact[key] > 0 and contact["pair_curve"] == "smooth":
            raise err(f"contact.{key}", "friction between segments needs "
                                        "contact.pair_curve = 'segments'")
        if contact[key] > 0 and not contact[pairs]:
            raise err(f"contact.{key}", f"applies to segments in contact: set "
                                        f"contact.{pairs} = true")
        if contact[key] > 0 and not scene["material"]["dynamic"]:
            raise err(f"contact.{key}", "friction depends on the velocity: it needs a "
                                        "dynamic rod (material.density > 0)")


def touching(scene: Scene) -> bool:
    """Obstacles, self-contact or contact between rods."""
    c = scene["contact"]
    return bool(scene["obstacles"] or c["self"] or c["between_rods"])


def segment_pairs(scene: Scene) -> bool:
    """Self-contact or contact between rods (rod/pair_contact.py)."""
    return bool(scene["contact"]["self"] or scene["contact"]["between_rods"])


def section_radius(scene: Scene) -> float | None:
    """The radius of a circle or tube [section], else None."""
    sec = scene["section"]
    return {"circle": sec["radius"], "tube": sec["outer_radius"]}.get(sec["shape"])


def obstacles(scene: Scene) -> list:
    """rod.contact.Obstacle of each [[obstacles]] entry."""
    from ..rod.contact import Obstacle
    out = []
    for ob in scene["obstacles"]:
        given = {key: tuple(ob[key]) for key in ("point", "normal", "centre", "axis")
                 if ob[key] is not None}       # the shape's keys only (checked above)
        out.append(Obstacle(ob["shape"], radius=ob["radius"] or 0.0,
                            length=ob["length"] or 0.0, friction=ob["friction"], **given))
    return out


def contact_law(scene: Scene, params):
    """rod.contact.ContactLaw of [contact] (defaults: gap r/10, stiffness from the rod and
    dt, slip tolerance 1e-3 L / t_end), None without contact."""
    from ..rod.contact import ContactLaw, default_stiffness
    if not touching(scene):
        return None
    c, geo, tim = scene["contact"], scene["geometry"], scene["time"]
    stiffness = c["stiffness"] or default_stiffness(params.density, params.A, geo["length"],
                                                    geo["n_cells"], tim["dt"])
    return ContactLaw(c["radius"], c["gap"] or c["radius"] / 10, stiffness,
                      c["slip_tolerance"] or 1e-3 * geo["length"] / tim["t_end"],
                      self=c["self"], between_rods=c["between_rods"],
                      self_friction=c["self_friction"],
                      between_rods_friction=c["between_rods_friction"],
                      pair_curve=c["pair_curve"])


def contact_solver_options(scene: Scene) -> dict:
    """Obstacles: Newton to rtol 1e-8 (the dynamic rod's 1e-4 accepts a step whose
    residual is dominated by the barrier's: docs/contact.md) unless time.rtol is given;
    friction: with a backtracking line search (the sticking law's Newton steps overshoot
    without one); segment pairs: without PETSc's divergence test."""
    if not touching(scene):
        return {}
    options = {} if "rtol" in scene.given["time"] else {"snes_rtol": 1e-8}
    c = scene["contact"]
    if any(ob["friction"] > 0 for ob in scene["obstacles"]) or c["self_friction"] > 0 \
            or c["between_rods_friction"] > 0:
        options["snes_linesearch_type"] = "bt"
    if segment_pairs(scene):    # a pair's barrier may raise the residual 1e4-fold on the
        options["snes_divergence_tolerance"] = -1.0     # way to its root: no divergence stop
    return options
