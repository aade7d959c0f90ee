"""Model selection: the least model a scene needs, with the reason.

    ode      quasi-static homogeneous torsion: constant coefficients, nu = 0, no distributed
             couple, end torsion or end rotation.  Then u = phi_s and u_d stay homogeneous
             (every point obeys the same ODE from the same data; under a prescribed end
             rotation the homogeneous twist u = Phi(t) satisfies int u ds = Phi), so the
             PDE reduces exactly to the 2x2 system of eqs. ``twist``, ``nattwist``.
    torsion  isolated torsion otherwise (inertia, s-dependent coefficients, a distributed
             couple): TorsionModel, the PDE of eqs. ``phieq``, ``upeq``.
    rod      a 3-D rod material (tensors), natural curvature, forces: RodModel.

:func:`at_rest` selects, for ``dolfin-rod buckle``, the rod at rest that the analysis runs.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass

from .rules import rod_rotations
from .schema import Scene, SceneError, parse_scene

__all__ = ["Choice", "select_model", "at_rest"]

ORDER = ("ode", "torsion", "rod")


@dataclass(frozen=True)
class Choice:
    model: str      # "ode" | "torsion" | "rod"
    reason: str
    forced: bool = False


def _needs(scene: Scene) -> tuple[str, str]:
    """The least model and why."""
    if scene.is_rod_material:
        return "rod", "a 3-D rod material (stiffness/viscosity tensors or a section) is given"
    mat, lds = scene["material"], scene["loads"]
    not_constant = [k for k in ("alpha", "alpha_d", "mu", "mu_d", "nu")
                    if not mat[k].is_constant]
    if not_constant:
        return "torsion", (f"{', '.join(not_constant)} varies along s, so the twist is not "
                           "homogeneous: the isolated-torsion PDE")
    if mat["nu"].constant != 0.0:
        return "torsion", ("nu > 0: rotary inertia makes the twist non-homogeneous (waves): "
                           "the isolated-torsion PDE")
    if lds["distributed_couple"] is not None:
        return "torsion", ("a distributed couple makes the torsion vary along s: the "
                           "isolated-torsion PDE")
    end = "end rotation" if scene["boundary"]["end"] == "rotation" else "end torsion"
    return "ode", (f"quasi-static (nu = 0) homogeneous torsion with constant coefficients, "
                   f"no distributed couple and an {end}: the PDE reduces exactly to the 2x2 "
                   "ODE of eqs. twist/nattwist")


def select_model(scene: Scene) -> Choice:
    """The model that runs the scene; raises SceneError if a forced model cannot."""
    need, reason = _needs(scene)
    requested = scene["scene"]["model"]
    if requested == "auto":
        choice = Choice(need, reason)
    elif ORDER.index(requested) < ORDER.index(need) or (requested != "rod" and need == "rod"):
        raise scene.error("scene.model", f"the {requested!r} model cannot run this scene: "
                                         f"it needs {need!r} ({reason})")
    elif requested == "rod" and not scene.is_rod_material:
        raise scene.error("scene.model", "the 'rod' model needs a 3-D rod material "
                                         "(material.stiffness, viscosity, density)")
    else:
        choice = Choice(requested, f"forced by scene.model (the least model would be "
                                   f"{need!r}: {reason})", forced=True)
    if choice.model == "ode":
        choice = Choice(choice.model, choice.reason + _ode_time_keys(scene), choice.forced)
    return choice


def _ode_time_keys(scene: Scene) -> str:
    """The ODE model has no PETSc TS path and uses time.scheme only with ode_solution =
    "scheme": integrator = "ts", or a scheme with an explicit ode_solution = "exact", is
    an error; a scheme kept for a forced PDE run is named as unused in the reason.  Nor
    does it save a state: checkpoints and a start from a saved state are errors too."""
    tim, given = scene["time"], scene.given["time"]
    for table, key in (("outputs", "checkpoint_every"), ("outputs", "final_checkpoint"),
                       ("initial", "from_run")):
        if scene[table][key]:      # the ODE is solved as a whole: no state between steps
            raise scene.error(f"{table}.{key}", "the 'ode' model (chosen: quasi-static "
                              "homogeneous torsion, solved as a whole) has no saved state: "
                              "set scene.model = \"torsion\" (the same equations as a PDE)")
    if tim["integrator"] == "ts":
        raise scene.error("time.integrator", "the 'ode' model (chosen: quasi-static "
                          "homogeneous torsion) has no PETSc TS path: drop integrator = "
                          "\"ts\" or set scene.model = \"torsion\"")
    if "scheme" in given and tim["ode_solution"] == "exact" and "ode_solution" in given:
        raise scene.error("time.scheme", "ode_solution = \"exact\" solves the ODE exactly "
                          "and uses no time scheme: drop time.scheme or set ode_solution = "
                          "\"scheme\"")
    if "scheme" in given and tim["ode_solution"] == "exact":
        return (f"; time.scheme = {tim['scheme']!r} is not used: the ODE is solved exactly "
                "(time.ode_solution = \"exact\"); the scheme applies when the scene runs as "
                "the torsion PDE (scene.model = \"torsion\") or with time.ode_solution = "
                "\"scheme\"")
    return ""


def at_rest(scene: Scene) -> tuple[dict, str] | None:
    """For ``dolfin-rod buckle``: the overrides that put a quasi-static scene whose
    geometry.rotations = "auto" picks quaternions only for its rate-dependent forces
    (Kelvin-Voigt viscosity M, N, drag) on rotation vectors, and a note saying so; None
    when nothing is to change.  Buckling is about equilibria at rest, where these forces
    vanish (docs/stability.md): the rod without them has the same critical loads; its
    pre-load is reached at the load's end value, without the viscous lag."""
    mat = scene["material"]
    if mat["dynamic"] or "rotations" in scene.given["geometry"] or \
            rod_rotations(scene) != "quaternion":
        return None
    raw = tomllib.loads(scene.text).get("material", {})
    visc = {k: v for k, v in raw.get("viscosity", {}).items() if k not in ("M", "N")}
    overrides = {"material.viscosity": visc or None, "material.drag": None,
                 "material.rotational_drag": None}
    if mat["model"] == "kelvin_voigt":
        overrides["material.model"] = "hyperelastic"
    try:
        scene = parse_scene(scene.text, scene.source, scene.name, overrides)
    except SceneError:
        return None
    if rod_rotations(scene) != "rotation_vector":
        return None
    return overrides, ("geometry.rotations = 'auto': the analysis runs the rod on rotation "
                       "vectors without its Kelvin-Voigt viscosity (M, N) and drag, which "
                       "vanish at rest (the critical loads are those of the rod at rest)")
