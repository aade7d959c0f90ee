"""A rod scene's physical input (issue 25 item 1): [section] shape and dimensions,
material.youngs_modulus with shear_modulus or poisson_ratio, density in kg/m^3,
natural_stiffness_ratio and relaxation_time, fluid_viscosity (slender-body drag) -> the
tensors the rod reads (rod/sections.py),
written into the scene's material table as if given, and recorded in
``scene["material"]["derived"]`` (printed by ``dolfin-rod check``, in summary.json).
"""

from __future__ import annotations

import numpy as np

from ..rod import sections
from .scene import Scene
from .values import Coefficient, Tensor

SECTION_DIMENSIONS = {"circle": ("radius",), "ellipse": ("semi_axes",),
                      "rectangle": ("sides",), "tube": ("outer_radius", "inner_radius")}
ELASTIC = ("youngs_modulus", "shear_modulus", "poisson_ratio", "natural_stiffness_ratio")
# the physical key each derived tensor comes from (fit names it: fit/inputs.py)
SOURCES = {"A": "youngs_modulus", "B": "youngs_modulus", "A_d": "youngs_modulus",
           "B_d": "youngs_modulus", "section_inertia": "density", "M_d": "relaxation_time",
           "N_d": "relaxation_time", "drag": "fluid_viscosity"}


def apply_physical_input(scene: Scene) -> None:
    """Derive the tensors of the physical keys; SceneError naming the key for overlapping
    or missing ones.  A scene without them is left as it is."""
    mat, err = scene["material"], scene.error
    section = _section(scene)
    derived: dict = {}
    if section is not None:
        derived["section"] = {"area": section.area, "I11": section.I11, "I22": section.I22,
                              "J": section.J}
    if mat["youngs_modulus"] is not None:
        derived.update(_elastic(scene, section))
    else:
        for key in ELASTIC[1:]:
            if mat[key] is not None:
                raise err(f"material.{key}", "needs material.youngs_modulus (and a "
                                             "[section])")
    if section is not None and mat["density"] is not None:
        derived.update(_mass(scene, section))
    if mat["relaxation_time"] is not None:
        derived.update(_relaxation(scene))
    if mat["fluid_viscosity"] is not None:
        derived.update(_fluid_drag(scene))
    mat["derived"] = derived or None


def _section(scene: Scene):
    sec, err = scene["section"], scene.error
    shape = sec["shape"]
    for key in ("radius", "semi_axes", "sides", "outer_radius", "inner_radius",
                "shear_factor"):
        if sec[key] is not None and (shape is None or (
                key != "shear_factor" and key not in SECTION_DIMENSIONS[shape])):
            needs = [s for s, dims in SECTION_DIMENSIONS.items() if key in dims]
            raise err(f"section.{key}", f"a dimension of section.shape = "
                                        f"{' | '.join(map(repr, needs)) or 'any'}; "
                                        f"shape is {shape!r}")
    if shape is None:
        return None
    dims = SECTION_DIMENSIONS[shape]
    for key in dims:
        if sec[key] is None:
            raise err(f"section.{key}", f"missing: a {shape} section needs "
                                        f"{', '.join('section.' + d for d in dims)} (m)")
    values = [v for d in dims for v in np.atleast_1d(sec[d])]
    try:
        return getattr(sections, shape)(*values)
    except ValueError as bad:
        raise err(f"section.{dims[-1]}", str(bad)) from None


def _elastic(scene: Scene, section) -> dict:
    mat, err = scene["material"], scene.error
    if section is None:
        raise err("material.youngs_modulus", "needs a [section] (shape and dimensions) to "
                                             "give the stiffnesses")
    stiff = mat["stiffness"] or {}
    for k in stiff:
        raise err(f"material.stiffness.{k}", "give either the tensors (material.stiffness) "
                                             "or material.youngs_modulus with a [section], "
                                             "not both")
    if (mat["shear_modulus"] is None) == (mat["poisson_ratio"] is None):
        raise err("material.shear_modulus", "give exactly one of material.shear_modulus and "
                                            "material.poisson_ratio with youngs_modulus")
    evolving = mat["model"] == "evolving"
    if evolving != (mat["natural_stiffness_ratio"] is not None):
        raise err("material.natural_stiffness_ratio",
                  "the evolving model with youngs_modulus needs it (A_d = r A, B_d = r B)"
                  if evolving else f"the {mat['model']} model has no natural strains")
    material = sections.Material(mat["youngs_modulus"], mat["shear_modulus"],
                                 mat["poisson_ratio"])
    factor = scene["section"]["shear_factor"]
    try:
        tensors = sections.section_parameters(section, material, factor,
                                              mat["natural_stiffness_ratio"])
    except ValueError as bad:
        key = "poisson_ratio" if mat["poisson_ratio"] is not None else "shear_modulus"
        hint = ("; a rod whose shear stiffness is not an isotropic solid's (PyElastica's "
                "Timoshenko beam: G = E/100) gives material.stiffness instead: A = (E I_22, "
                "E I_11, G J), B = (k G a, k G a, E a)") if "Poisson" in str(bad) else ""
        raise err(f"material.{key}", str(bad) + hint) from None
    E, G, nu = material.moduli()
    names = [k for k in ("A", "B", "A_d", "B_d") if k in tensors]
    mat["stiffness"] = {k: Tensor((np.diag(tensors[k]),)) for k in names}
    k1, k2 = section.shear_factors(nu) if factor is None else factor
    return {"shear_modulus": G, "poisson_ratio": nu, "shear_factors": [k1, k2],
            **{k: list(tensors[k]) for k in names}}


def _mass(scene: Scene, section) -> dict:
    """density [kg/m^3] with a section: rho A = rho a, section_inertia = rho (I11, I22)."""
    mat, err = scene["material"], scene.error
    if "section_inertia" in scene.given["material"]:
        raise err("material.section_inertia", "derived from the [section] and "
                                              "material.density (kg/m^3): drop it")
    rho = mat["density"]
    if not rho.is_constant:
        raise err("material.density", "with a [section], density is a number in kg/m^3")
    rho = rho.constant
    mat["density"] = Coefficient(constant=rho * section.area)
    mat["section_inertia"] = (rho * section.I11, rho * section.I22)
    return {"density": rho * section.area, "section_inertia": list(mat["section_inertia"])}


def _relaxation(scene: Scene) -> dict:
    """M_d = tau_u (A + A_d), N_d = tau_v (B + B_d) from the (given or derived) tensors,
    times the rod's length for the uniform variant (rod/sections.py)."""
    mat, err = scene["material"], scene.error
    if mat["model"] != "evolving":
        raise err("material.relaxation_time", f"the {mat['model']} model has no natural "
                                               "strains to relax")
    visc = dict(mat["viscosity"] or {})
    for k in ("M_d", "N_d"):
        if k in visc:
            raise err(f"material.viscosity.{k}", "give either material.relaxation_time or "
                                                 "the viscosities M_d, N_d, not both")
    stiff = mat["stiffness"] or {}
    for k in ("A", "B", "A_d", "B_d"):
        if k not in stiff:
            raise err("material.relaxation_time", f"needs the stiffness {k} (material."
                                                  "stiffness or youngs_modulus)")
    # the uniform law integrates over s (eq. unatevolunif): tau needs one more factor L
    length = scene["geometry"]["length"] if mat["variant"] == "uniform" else 1.0
    out = {}
    for tau, name, (a, a_d) in zip(mat["relaxation_time"], ("M_d", "N_d"),
                                   (("A", "A_d"), ("B", "B_d"))):
        terms = _sum_terms(stiff[a].terms, stiff[a_d].terms)
        visc[name] = Tensor(tuple(tau * length * t for t in terms))
        first = visc[name].terms[0]
        out[name] = ("polynomial in s" if len(terms) > 1 else np.diag(first).tolist()
                     if not np.any(first - np.diag(np.diag(first))) else first.tolist())
    mat["viscosity"] = visc
    return out


def _fluid_drag(scene: Scene) -> dict:
    """material.drag = (c_n, c_n, c_t) of slender-body theory from fluid_viscosity, the
    section's (outer) radius and the rod's length (sections.slender_body_drag)."""
    mat, sec, err = scene["material"], scene["section"], scene.error
    if "drag" in scene.given["material"]:
        raise err("material.drag", "give either material.drag or material.fluid_viscosity "
                                   "(slender-body drag), not both")
    radius = {"circle": sec["radius"], "tube": sec["outer_radius"]}.get(sec["shape"])
    if radius is None:
        raise err("material.fluid_viscosity", "needs a circle or tube [section] (its radius "
                                              f"r in c_n = 4 pi mu / ln(L/r)); shape is "
                                              f"{sec['shape']!r}")
    try:
        c = sections.slender_body_drag(mat["fluid_viscosity"], scene["geometry"]["length"],
                                       radius)
    except ValueError as bad:
        raise err("material.fluid_viscosity", str(bad)) from None
    mat["drag"] = Tensor((np.diag(c),))
    return {"drag": list(c)}


def _sum_terms(p: tuple, q: tuple) -> tuple:
    """The terms of the polynomial tensor sum p(s) + q(s)."""
    n = max(len(p), len(q))
    zero = np.zeros((3, 3))
    return tuple((p[i] if i < len(p) else zero) + (q[i] if i < len(q) else zero)
                 for i in range(n))


# the derived quantities' units in SI (the physical keys' documented units) and, for
# another unit system (schema.UNITS), the same dimensions in its length L, force F, time T
DERIVED_DIMENSIONS = {
    "A": ("N m^2", "F L^2"), "B": ("N", "F"), "A_d": ("N m^2", "F L^2"), "B_d": ("N", "F"),
    "M_d": ("N m^2 s", "F L^2 T"), "N_d": ("N s", "F T"), "drag": ("N s/m^2", "F T/L^2"),
    "density": ("kg/m", "F T^2/L^2"), "section_inertia": ("kg m", "F T^2"),
    "shear_modulus": ("Pa", "F/L^2"), "poisson_ratio": ("", ""), "shear_factors": ("", "")}
NOTES = {"drag": " (c_n, c_n, c_t)", "density": " (rho A)",
         "section_inertia": " (rho I_11, rho I_22)"}


def _unit(key: str, system: dict | None) -> str:
    """The unit of a derived quantity (a key of DERIVED_DIMENSIONS, or "L" for a
    length) in the unit ``system`` (schema.UNITS's; None: SI; dimensionless: none)."""
    si, dims = DERIVED_DIMENSIONS.get(key, ("m", key))
    if system is None or not dims:
        return si
    if system["length"] == "1":
        return ""
    return "".join(system[{"L": "length", "F": "force", "T": "time"}[c]]
                   if c in "LFT" else c for c in dims)


def describe(derived: dict, units: dict | None = None) -> list[str]:
    """Lines for ``dolfin-rod check``: the derived tensors with their units, in the
    scene's unit system ``units`` (its schema.UNITS entry; None: SI, the physical keys'
    documented units)."""
    lines = []
    length = _unit("L", units)
    if "section" in derived:
        s = derived["section"]
        area, moment = (f" {length}^2", f" {length}^4") if length else ("", "")
        lines.append(f"section: area {s['area']:.6g}{area}, I_11 {s['I11']:.6g}{moment}, "
                     f"I_22 {s['I22']:.6g}{moment}, J {s['J']:.6g}{moment}")
    for key in DERIVED_DIMENSIONS:
        if key in derived:
            value = derived[key]
            text = (f"{value:.6g}" if isinstance(value, float) else
                    "[" + ", ".join(f"{x:.6g}" for x in np.ravel(value)) + "]"
                    if not isinstance(value, str) else value)
            unit = (" " + _unit(key, units)).rstrip()
            lines.append(f"{key} = {text}{unit}{NOTES.get(key, '')}")
    return lines
