"""The TOML scene schema: parsing, defaults and validation.

A scene is one TOML file; every table and key is listed in ``SCHEMA`` below with its
type, default and rule.  Anything wrong with a scene (bad TOML, an unknown key, a wrong
type, a missing required value, a non-physical value, an inconsistent combination) is
reported as ONE :class:`SceneError` naming the file, the key path and the reason, e.g.

    scenes/bad.toml: [material.alpha]: must be > 0, got -1.0

Nothing else escapes :func:`load_scene` / :func:`parse_scene` (the test suite fuzzes
them with hypothesis).  Torsion scenes use the paper's dimensionless Section 5 variables
(alpha, alpha_d, mu, mu_d, nu, errata item 5); 3-D rod scenes use the tensors of the
quadratic energy (eq. ``quadenergy``) and the viscosities M, N, M_d, N_d in the user's
consistent units.  A key that does not apply to the scene's model (a torsion key in a
rod scene, a rod key in a torsion scene, natural-strain data of a non-evolving rod, ...)
is an error.

The value checkers live in ``scenes/values.py`` and ``scenes/histories.py``, the rules
across keys in ``scenes/rules.py``; this module holds the table and the entry points.
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..checks import (DEGREE, MAX_STEP_CUTS, MIN_LENGTH, N_CELLS, NEWTON_ATOL,
                      NEWTON_FORCE_TOL, NEWTON_RTOL, ODE_SOLUTION, PREDICTOR, ROD_MODEL,
                      ROTATION_UNKNOWNS, SCENE_BYTES, SCHEME, STARTING_ACCELERATIONS, TS_ATOL,
                      TS_RTOL, VARIANT,
                      read_regular_file)
from ..rod.rotation_choice import ROTATIONS
from ..rod.sections import SHAPES as SECTION_SHAPES
from .builders import initial_centre_lines
from .contact import check_initial_contact, touching
from .histories import HistorySpec, distributed, history, muscle
from .rules import check_combinations
from .scene import Scene, SceneError
from .systems import shadowing_rod, validate_system
from .values import (BadValue, Coefficient, Tensor, boolean, choice, coefficient,
                     friction_coefficients,
                     names_or_boolean, damping_tensor, drag, entry_point, integer,
                     load_entry_point, path_problem, path_text,
                     petsc_table, points3, index_triples, positive_pair, real, run_name, safe_name, scheme_name,
                     section_inertia, spring_table, starting_shape, string, tensor_table,
                     toml_value,
                     ts_type_name,
                     type_name, vector3, velocity_field)

__all__ = ["SceneError", "Scene", "Coefficient", "HistorySpec", "Tensor", "load_scene",
           "parse_scene", "load_entry_point", "SCHEMA", "SCHEMA_NOTES", "MODEL_NAMES",
           "path_problem"]

MODEL_NAMES = ("auto", "ode", "torsion", "rod")
VARIANTS = ("local", "uniform")
ROD_MODELS = ("evolving", "kelvin_voigt", "hyperelastic")
ROD_ENDS = ("clamped", "pinned", "free")
CONSTRAINTS = ("none", "unshearable", "inextensible_unshearable")
OBSTACLE_SHAPES = ("plane", "sphere", "cylinder", "mesh")

# the fields that colour the 3-D pictures (output/animation.py), the panels of
# histories.png (output/plots.py) and the unit systems of a scene's axes
COLOURS = ("auto", "u", "v", "u_d", "v_d", "n", "m", "xi")
PANELS = ("tip_deflection", "tip_rotation", "end_torque", "force_extension", "reactions",
          "contact", "stability", "twist", "energy", "power_residual")

# quantity kind -> unit per unit system
UNITS = {       # momentum: force x time; angular momentum: moment x time
    "SI": {"length": "m", "time": "s", "force": "N", "moment": "N m", "energy": "J",
           "power": "W", "angle": "rad", "momentum": "N s", "angular_momentum": "N m s"},
    "pN-nm-s": {"length": "nm", "time": "s", "force": "pN", "moment": "pN nm",
                "energy": "pN nm", "power": "pN nm/s", "angle": "rad",
                "momentum": "pN s", "angular_momentum": "pN nm s"},
    # molecular dynamics' nanoseconds (mass unit pN ns^2/nm = 1e-21 kg)
    "pN-nm-ns": {"length": "nm", "time": "ns", "force": "pN", "moment": "pN nm",
                 "energy": "pN nm", "power": "pN nm/ns", "angle": "rad",
                 "momentum": "pN ns", "angular_momentum": "pN nm ns"},
    # engineering's millimetres (stress N/mm^2 = MPa; mass t, or g with ms)
    "mm-N-s": {"length": "mm", "time": "s", "force": "N", "moment": "N mm",
               "energy": "N mm", "power": "N mm/s", "angle": "rad",
               "momentum": "N s", "angular_momentum": "N mm s"},
    "mm-N-ms": {"length": "mm", "time": "ms", "force": "N", "moment": "N mm",
                "energy": "N mm", "power": "N mm/ms", "angle": "rad",
                "momentum": "N ms", "angular_momentum": "N mm ms"},
    "dimensionless": dict.fromkeys(("length", "time", "force", "moment", "energy",
                                    "power", "momentum", "angular_momentum"), "1")
    | {"angle": "rad"},       # the torsion scenes' Section 5.1 variables
}


REQUIRED = object()


@dataclass(frozen=True)
class Key:
    check: Callable[[Any], Any]
    default: Any = REQUIRED
    doc: str = ""


SCHEMA_NOTES = """\
**Two kinds of scene.** A scene with `material.stiffness`/`viscosity` (or density,
section_inertia, drag, or a `[section]` with `material.youngs_modulus`) is a **3-D rod**
(RodModel): it is in the user's consistent units, e.g. SI: lengths in m, time in s,
A = (EI_1, EI_2, GJ) in N m^2, B = (GA_1, GA_2, EA) in N, M, M_d in N m^2 s, N, N_d in
N s, density rho A in kg/m, section_inertia rho I in kg m, gravity in m/s^2, forces in
N, couples in N m, distributed loads per metre.  **Physical input** instead of tensors: a
`[section]` (shape and dimensions in m) with `material.youngs_modulus` and
`shear_modulus` or `poisson_ratio` (Pa) gives A, B; with it `material.density` is the
mass density in kg/m^3 (rho A and section_inertia follow); `natural_stiffness_ratio`
gives A_d, B_d and `relaxation_time` (s) M_d, N_d (rod/sections.py; `dolfin-rod check`
prints the derived tensors, summary.json records them; `scenes/gravity_cantilever.toml`
is an SI example).  Giving a tensor and the physical key that derives it is an error.  Otherwise it is a **torsion** scene
(the ODE or TorsionModel): the paper's dimensionless Section 5.1 variables (alpha, alpha_d,
mu, mu_d, nu; s in [0, 1], errata item 5).  Keys marked "3-D rod:" or "torsion:" belong to
one kind; giving one to the other kind is an error.

**Values: one load syntax.** Every load and prescribed motion is a table `{type =
"constant" | "step" | "ramp" | "smooth_step" | "table", value, t0, duration, follower,
profile}`: `value` (a number; rod loads and end motions a vector `[x, y, z]`), `t0` (the
step's time, the ramp's and smooth step's start; default 0), `duration` (ramp, smooth
step), or `times` and `values` (table: piecewise linear; rod: `values` of 3-vectors);
`follower = true` for rod loads (components in the material frame, rotating with the
section), `profile` (a number or `{polynomial}` in s) for distributed loads, which are
value profile(s) history(t) per unit length, `s` (where, required) for point loads.
`type` defaults to "constant".  E.g.
`end_force = { type = "ramp", value = [0.0, 0.0, 2.0], t0 = 1.0, duration = 0.5 }`,
`distributed_force = { type = "step", value = [0.1, 0.0, 0.0], profile = { polynomial =
[1.0, -1.0] } }`, `point_force = { s = 0.5, type = "ramp", value = [0.0, -1.0, 0.0],
duration = 1.0 }`.  The old distributed form `{value, profile, history = {...}}` is an
error that shows its new spelling.
A torsion coefficient or a density/drag/profile is a number or `{polynomial = [c0, c1,
...]}` in s (a drag may instead be a tensor in the directors' frame, `[c_1, c_2, c_3]` or
3x3: anisotropic).  A rod tensor (A, B, A_d, B_d, M, N, M_d, N_d) is `[a, b, c]` (diagonal),
`[[..], [..], [..]]` (a full symmetric 3x3 matrix) or `{polynomial = [T0, T1, ...]}`
(T(s) = T0 + T1 s + ..., each T_k diagonal or 3x3; s in [0, L]).  The uniform variant's
law integrates over s (eq. unatevolunif), so its M_d carries a length factor:
switching variant on a rod with L != 1 rescales time by L.

**Several rods** (a RodSystem, docs/systems.md).  `[[rods]]` tables, one per rod: `name`
(unique; the rod's output columns are `<name>.<key>`), `position` (its s = 0 end, m),
`orientation` (a rotation vector turning e_3 into its initial tangent), and its own
`geometry`, `section`, `material`, `boundary`, `loads`, `initial` as inline tables laid
over the scene's tables key by key (a `section` with a `shape` replaces the scene's
[section]; an error names `rods[k].<table>.<key>`;
`material.model`, `variant`, `constraints`, `energy` and `geometry.rotations` are shared
and given in the scene's tables only; `initial.natural_*` are each rod's own (or the
scene's for every rod); a rod's starting
state, `initial.shape`, `position`, `orientation`, velocities, is in its placed frame,
and the starts of joined rods must meet as the joint holds them).  `[[joints]]` tables: `kind` ("rigid": position and rotation tied,
"ball": position tied, "hinge": position tied, rotations equal up to a turn about
`axis`), `rods = [a, b]`, `point = [x, y, z]` (a node of both rods at t = 0, not a
supported end), `axis = [x, y, z]` (a hinge's, a unit vector at t = 0, turning with the
rods), `name` (its reaction columns `joint_<name>_force_{xyz}`,
`joint_<name>_couple_{xyz}`).  Examples: `scenes/frame.toml`, `double_pendulum.toml`,
`tripod.toml`, `hinged_door.toml`.

**What a run can follow** (checked by `dolfin-rod check`, exit 2 naming the key).  A rod
with inertia (density > 0; torsion: nu > 0) cannot follow a jump of a prescribed end
motion (a `step`, at any `t0`), nor, unless `time.adaptive`, a ramp, smooth step or
table segment shorter than `time.dt`.  Prescribed rotations may turn one end against the
other by less than 2 rad per cell (`geometry.n_cells` > angle/2, checks.MAX_CELL_TURN);
a run whose cell turns by more (end couples too) stops, exit 3 naming the cells needed.  A `material.energy`
must be stress-free and convex at the natural strains and convex at the start strains
(`natural_state.start_state_problem`).
"""

R = "3-D rod: "
T = "torsion: "
SCHEMA: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key(run_name, None, "run name, a folder name: letters, digits, '.', '_', '-' "
                                   "(default: the file's stem, other characters as '_')"),
        "description": Key(string, "", "free text"),
        "model": Key(choice(*MODEL_NAMES), "auto", "auto | ode | torsion | rod"),
        "units": Key(choice(*UNITS), None, " | ".join(UNITS) + ": the unit system the "
                     "scene's numbers are in, shown on the axes of the plots (default: "
                     "\"scene units\"); the physical keys (youngs_modulus, density, "
                     "fluid_viscosity: Pa, kg/m^3, Pa s in SI) then in its units (mm-N-s: "
                     "MPa, t/mm^3, MPa s; mm-N-ms: MPa, g/mm^3, MPa ms)"),
    },
    "geometry": {
        "length": Key(real(MIN_LENGTH), 1.0, f"rod length L >= {MIN_LENGTH:g} (torsion: "
                      "dimensionless, must be 1)"),
        "n_cells": Key(integer(1, 100_000), N_CELLS, "number of cells along s"),
        "degree": Key(integer(1, 3), DEGREE, T + "Lagrange degree of phi (the rod is P1)"),
        "reference_curvature": Key(vector3(), (0.0, 0.0, 0.0),
                                   R + "curvature u_ref of the stress-free initial shape (a "
                                   "helix or circle; not a natural strain)"),
        "reference_stretch": Key(vector3(), (0.0, 0.0, 1.0),
                                 R + "stretch v_ref of the stress-free initial shape "
                                 "(v_ref,3 > 0)"),
        "reference_shape": Key(starting_shape, None,
                               R + "the stress-free shape as a curve instead of "
                               "reference_curvature/stretch, from the rod's start along e3 "
                               "(then placed as the rod): {type = \"polyline\", points = "
                               "[[x, y, z], ...], normal = [1, 0, 0]} (a bent frame as one "
                               "rod: split at every corner into straight pieces joined "
                               "rigidly, its n_cells shared in proportion to their "
                               "lengths; `dolfin-rod check` says how), or an arc or helix "
                               "(as initial.shape)"),
        "closed": Key(boolean, False, R + "a closed rod (ring): its end welded to its start "
                      "(the support boundary.start: clamped, the weld point held, or free, a "
                      "free ring of a dynamic rod); it starts as the circle of circumference "
                      "length in the (d1, d3) plane of its start, bending towards d1 (placed "
                      "by initial.position, orientation; no initial.shape), its stress-free "
                      "shape geometry.reference_curvature's (straight by default: bent to "
                      "EI/R); one rod only (docs/systems.md, \"Closed rods\")"),
        "excess_link": Key(real(), 0.0, R + "a closed rod's linking number beyond its "
                           "natural twist, in turns: it starts planar (writhe 0) with this "
                           "much more twist than reference_curvature's third component "
                           "gives, and the weld keeps it (Lk = Tw + Wr); a DNA minicircle's "
                           "Delta Lk; above Michell's sqrt(3) A_1/A_3 turns (isotropic "
                           "bending) the planar ring is unstable and writhes"),
        "rotations": Key(choice(*ROTATIONS), ROTATION_UNKNOWNS,
                         R + "rotation unknowns: auto = rotation_vector (6 unknowns per "
                         "node; the fast default) for the local variant, no constraint and "
                         "the stepper: a dynamic rod with time.scheme unset or "
                         "generalized_alpha (on the rotation group), or a quasi-static rod "
                         "without Kelvin-Voigt viscosity M, N and drag whose end rotations "
                         "do not jump (any scheme; unset: generalized-alpha with algebraic "
                         "positions and rotations, the start in equilibrium with the loads "
                         "at t = 0); quaternion (+ gauge, velocities: any scheme or PETSc "
                         "TS) otherwise"),
    },
    "section": {
        "shape": Key(choice(*SECTION_SHAPES), None, R + "circle | ellipse | rectangle | tube: "
                     "the cross-section; with material.youngs_modulus it gives A, B, with "
                     "material.density (then in kg/m^3) rho A and section_inertia "
                     "(rod/sections.py; `dolfin-rod check` prints them)"),
        "radius": Key(real(0.0, True), None, R + "circle: radius (m)"),
        "semi_axes": Key(positive_pair, None, R + "ellipse: [a_1, a_2], semi-axes along d_1, "
                         "d_2 (m)"),
        "sides": Key(positive_pair, None, R + "rectangle: [b_1, b_2], sides along d_1, d_2 (m)"),
        "outer_radius": Key(real(0.0, True), None, R + "tube: outer radius (m)"),
        "inner_radius": Key(real(0.0), None, R + "tube: inner radius (m), < outer_radius"),
        "shear_factor": Key(positive_pair, None, R + "k or [k_1, k_2] in B = (k_1 G a, k_2 G "
                            "a, E a) (default: Cowper's by shape and Poisson's ratio; an "
                            "ellipse takes the circle's)"),
    },
    "material": {
        "variant": Key(choice(*VARIANTS), VARIANT, "local | uniform evolution law of the "
                       "natural strains (uniform: the M_d law integrates over s, so M_d "
                       "carries a length factor)"),
        "model": Key(choice(*ROD_MODELS), ROD_MODEL,
                     R + "evolving (natural strains evolve) | kelvin_voigt (viscosities M, "
                     "N only) | hyperelastic"),
        "energy": Key(entry_point, None,
                      R + "free energy psi(u_d, v_d, u, v): \"package.module:function\" "
                      "returning a UFL scalar (the scene's folder is on the import path); "
                      "default: eq. quadenergy with the stiffness tensors"),
        "alpha": Key(coefficient(True), None, T + "torsional stiffness (default 1)"),
        "alpha_d": Key(coefficient(True), None, T + "natural-twist stiffness (default 1)"),
        "mu": Key(coefficient(False), None, T + "Kelvin-Voigt viscosity (default 0)"),
        "mu_d": Key(coefficient(True), None, T + "natural-configuration viscosity (default 1)"),
        "nu": Key(coefficient(False), None, T + "rotary inertia (default 0: quasi-static)"),
        "stiffness": Key(lambda v: tensor_table(v, ("A", "B", "A_d", "B_d")), None,
                         R + "{A, B, A_d, B_d}: bending/torsion A = (EI_1, EI_2, GJ), "
                         "shear/axial B = (GA_1, GA_2, EA), natural-strain stiffnesses A_d, "
                         "B_d (evolving model); each a tensor (see above)"),
        "viscosity": Key(lambda v: tensor_table(v, ("M", "N", "M_d", "N_d")), None,
                         R + "{M, N, M_d, N_d}: Kelvin-Voigt M, N (default 0), natural-"
                         "configuration M_d, N_d (evolving model; the uniform variant's M_d, N_d carry one "
                         "more length factor than the local ones, docs/rod.md); each a tensor"),
        "youngs_modulus": Key(real(0.0, True), None, R + "E (Pa), with a [section] and "
                              "shear_modulus or poisson_ratio: A = (E I_22, E I_11, G J), B = "
                              "(k_1 G a, k_2 G a, E a) instead of material.stiffness"),
        "shear_modulus": Key(real(0.0, True), None, R + "G (Pa) (or poisson_ratio)"),
        "poisson_ratio": Key(real(-1.0, True, 0.5), None, R + "nu: G = E/(2 (1 + nu)) (or "
                             "shear_modulus)"),
        "natural_stiffness_ratio": Key(real(0.0, True), None, R + "r (evolving model, with "
                                       "youngs_modulus): A_d = r A, B_d = r B"),
        "relaxation_time": Key(positive_pair, None, R + "tau or [tau_u, tau_v] (s): the "
                               "natural strains' relaxation times at a held strain, M_d = "
                               "tau_u (A + A_d), N_d = tau_v (B + B_d) (uniform variant: "
                               "times geometry.length, its law integrating over s) instead "
                               "of viscosity.M_d, N_d (evolving model)"),
        "density": Key(coefficient(False), None, R + "mass per length rho A (kg/m; number or "
                       "{polynomial}); with a [section]: the mass density rho (kg/m^3, a "
                       "number), rho A = rho a and section_inertia = rho (I_11, I_22); > 0: "
                       "dynamic, 0 (default): quasi-static"),
        "section_inertia": Key(section_inertia, None, R + "I_11 = I_22 (a number) or [I_11, I_22]: "
                               "section mass moments per length (rho J, Section 2.2)"),
        "drag": Key(drag, None, R + "linear drag per length (N s/m^2): a number c or "
                    "{polynomial} in s, f = -c dr/dt (isotropic), or [c_1, c_2, c_3] (or "
                    "a 3x3 array) C in the directors' frame, f = -R C R^T dr/dt "
                    "(anisotropic: a fluid's resistive force, e.g. [c_n, c_n, c_t]); its "
                    "dissipation is in dissipation_rate"),
        "fluid_viscosity": Key(real(0.0), None, R + "mu (Pa s) of a Stokes fluid around the "
                               "rod, with a circle or tube [section]: material.drag = [c_n, "
                               "c_n, c_t], c_n = 4 pi mu / ln(L/r), c_t = c_n / 2 (slender-"
                               "body theory, PyElastica's SlenderBodyTheory; r the "
                               "section's (outer) radius, L geometry.length)"),
        "rotational_drag": Key(damping_tensor, None, R + "rotational damping C (N m s per "
                               "length): the couple -C W per length, W the angular velocity "
                               "(a number c: C = c I; [c_1, c_2, c_3] or a tensor); its "
                               "dissipation W.C W is in dissipation_rate"),
        "rotational_drag_frame": Key(choice("material", "spatial"), "material",
                                     R + "components of rotational_drag: material (C W, "
                                     "W and C in the directors' frame) | spatial (C w, w = R W "
                                     "and C in the fixed frame)"),
        "constraints": Key(choice(*CONSTRAINTS), "none",
                           R + "none | unshearable | inextensible_unshearable"),
    },
    "initial": {
        "natural_twist": Key(real(), None, T + "u_d at t = 0 (default 0)"),
        "natural_curvature": Key(vector3(), None, R + "u_d at t = 0 (evolving; default: "
                                 "the reference strains, i.e. unstressed)"),
        "natural_stretch": Key(vector3(), None, R + "v_d at t = 0 (evolving; default: "
                               "the reference strains)"),
        "position": Key(vector3(), None, R + "where the rod's start s = 0 is at t = 0 (a "
                        "length; default: the origin)"),
        "orientation": Key(vector3(), None, R + "rotation vector (rad) turning (e1, e2, e3) "
                           "into the start's directors (d1, d2, d3) (default 0: the rod "
                           "starts along e3)"),
        "shape": Key(starting_shape, None,
                     R + "starting centre line, in the start's frame (then placed by "
                     "position, orientation); the stress-free shape stays geometry."
                     "reference_curvature's (straight by default): {type = \"straight\", "
                     "stretch = 1} | {type = \"arc\", radius, stretch = 1} (bending towards "
                     "d1) | {type = \"helix\", radius, pitch, stretch = 1} (its axis (0, a, c)/"
                     "sqrt(a^2 + c^2) in the start's frame, a = radius, c = pitch/(2 pi): "
                     "nearly d2 for a tight coil; a coil with its axis along e3 needs "
                     "orientation = [pi/2, 0, 0]) | {type = "
                     "\"polyline\", points = [[x, y, z], ...], rest_arc_length = [0, ..., "
                     "L] (default: the polyline's own arc length, which must be L), normal = "
                     "[1, 0, 0] (gives d1)}; stretch, rest_arc_length: a pre-stretched start "
                     "(default: the stress-free shape)"),
        "velocity": Key(velocity_field, None, R + "velocity at t = 0 (length/time; dynamic "
                        "rods; held ends stay at rest): [x, y, z], or along the rod {value = "
                        "[x, y, z], profile = {polynomial = [c0, c1, ...]}} (value times "
                        "c0 + c1 s + ..., s the arc length from the start: a mode shape)"),
        "angular_velocity": Key(vector3(), None, R + "spatial angular velocity w at t = 0 "
                                "(rad/time; dynamic rods)"),
        "rotation_centre": Key(vector3(), None, R + "with angular_velocity: the rod starts "
                               "as a rigid body turning about this point, velocity + w x "
                               "(r - rotation_centre)"),
        "equilibrium": Key(boolean, False, R + "settle the positions and rotations in "
                           "static equilibrium with the loads at t = 0 from the starting "
                           "shape before the run (dynamic rods: quasi-static pre-loading; "
                           "quasi-static rods: a start far from equilibrium, such as a "
                           "knotted polyline of a straight rod, whose first solve fails; "
                           "natural strains kept): one Newton solve, and "
                           "where that fails (a large deflection) or no end holds the "
                           "rotation, in pseudo-time (docs/rod.md); needs an end support "
                           "(clamped, pinned, end rotation or spring) or obstacles to rest "
                           "on (docs/contact.md); a warning if the equilibrium it settles "
                           "in is unstable (a column above its buckling load)"),
        "acceleration": Key(choice(*STARTING_ACCELERATIONS), "balance",
                            R + "dynamic rods with rotation vectors: the accelerations the "
                            "first step starts from: balance (solved from the balance laws "
                            "at t = 0, friction read at the slip the first step would make: "
                            "a rod at rest held by friction starts held, one sliding starts "
                            "at Coulomb's force) | zero (a state known to be at rest whose "
                            "discrete balance is not exactly met: its imbalance is not "
                            "carried into the first steps' velocities; docs/contact.md)"),
        "from_run": Key(path_text, None, "start from the state a previous run saved (its "
                        "run folder, with outputs.final_checkpoint or checkpoint_every): positions, "
                        "rotations, velocities, natural strains (docs/scenes.md, \"Starting "
                        "from a previous run\"); the same rods, n_cells, degree, model and "
                        "rotations; loads, supports, time and outputs are this scene's, its "
                        "time starts at 0; no other [initial] key"),
        "from_time": Key(real(0.0), None, "with from_run: the saved state at this time of "
                         "the previous run (default: its last one; outputs.keep_checkpoints "
                         "keeps them all)"),
        "continue_integration": Key(boolean, False, "with from_run: continue the previous "
                                    "run's time integration (its multistep history, "
                                    "generalized-alpha's accelerations; the same integrator, "
                                    "scheme and dt): the two runs are then the one run whose "
                                    "loads change in the step after the saved state, to "
                                    "round-off (default: a new start from the state, as "
                                    "any run starts)"),
    },
    "boundary": {
        "start": Key(choice(*ROD_ENDS), "clamped", "s = 0: clamped | pinned | free "
                     "(torsion: clamped)"),
        "end": Key(choice("free", "rotation", "clamped", "pinned"), "free",
                   "s = L: free | clamped | pinned (rod); free | rotation (torsion: "
                   "prescribed end rotation)"),
        "end_rotation": Key(history(True), None, "torsion: history of Phi(t); 3-D rod: "
                            "rotation vector (value = [x, y, z]) superposed on the end's "
                            "initial rotation"),
        "start_rotation": Key(history(True), None, R + "as end_rotation, at s = 0"),
        "end_displacement": Key(history(True), None, R + "prescribed displacement of s = L "
                                "from its initial position (value = [x, y, z]); on a dynamic "
                                "rod a value at t = 0 (a constant, a step at t0 = 0) starts "
                                "the rod at rest in equilibrium with it"),
        "start_displacement": Key(history(True), None, R + "as end_displacement, at s = 0"),
        "end_slide": Key(vector3(), None, R + "unit axis [x, y, z] (any direction, e.g. "
                         "[0, 0, 1]) along which the clamped or pinned end s = L slides "
                         "freely: its position is held (or, on a coordinate axis, "
                         "end_displacement prescribed) across the axis only; a clamped end "
                         "keeps its rotation (or follows end_rotation, e.g. turning about "
                         "the axis); an end_force acts on it along the axis, the support "
                         "takes its part across (a weight on a sliding clamp); an axis off "
                         "the coordinate axes is held by a one-node link (any rotation "
                         "unknowns; not with time.integrator = 'ts')"),
        "start_slide": Key(vector3(), None, R + "as end_slide, at s = 0"),
        "end_turn": Key(vector3(), None, R + "unit axis [x, y, z] (spatial, any direction) "
                        "about which the clamped end s = L turns freely (a hinge; with "
                        "end_slide along the same axis a cylindrical joint): its rotation "
                        "is held about the other two axes only, a dead end_couple acts on "
                        "it about the axis; a start may turn the end about the axis only"),
        "start_turn": Key(vector3(), None, R + "as end_turn, at s = 0"),
        "end_spring": Key(spring_table, None, R + "a compliant support at s = L: "
                          "{translational = k or [k_x, k_y, k_z] (N/m, spatial), rotational = "
                          "k or [k_1, k_2, k_3] (N m/rad, material)} about the end's initial "
                          "position and rotation (energy 1/2 k |x - x_0|^2 + k (1 - cos phi) "
                          "per axis); translational where the position is free (or slides), "
                          "rotational where the rotation is free"),
        "start_spring": Key(spring_table, None, R + "as end_spring, at s = 0"),
    },
    "loads": {
        "end_torsion": Key(history(False), None, T + "applied torsion m(t) at s = 1"),
        "distributed_couple": Key(distributed, None,
                                  "l(s, t) per length, {type, value, t0, duration, follower, "
                                  "profile} = value profile(s) history(t) (torsion: value a "
                                  "number; rod: value = [x, y, z], follower = true for "
                                  "material components)"),
        "distributed_force": Key(distributed, None, R + "as distributed_couple, a force"),
        "gravity": Key(vector3(), None, R + "g = [x, y, z]: the distributed force rho_A g "
                       "(needs density > 0)"),
        "end_force": Key(history(True, True), None, R + "force at s = L, {type, value, t0, "
                         "duration, follower}: value = [x, y, z] (or a table of 3-vectors); "
                         "follower = true: material components (rotating with the end)"),
        "end_couple": Key(history(True, True), None, R + "couple at s = L (as end_force)"),
        "start_force": Key(history(True, True), None, R + "force at s = 0 (as end_force)"),
        "start_couple": Key(history(True, True), None, R + "couple at s = 0 (as end_force)"),
        "point_force": Key(history(True, True, point=True), None, R + "a concentrated force "
                           "at the point s of the rod, {s, type, value, t0, duration, "
                           "follower} (as end_force; 0 <= s <= geometry.length; between "
                           "nodes shared by the two nearest as the P1 hat functions there)"),
        "point_couple": Key(history(True, True, point=True), None, R + "a concentrated "
                            "couple at the point s (as point_force)"),
        "muscle": Key(muscle, None, R + "an active bending moment travelling along the rod "
                      "(PyElastica's MuscleTorques): {axis = [x, y, z], amplitude, period, "
                      "wave_length, phase = 0, ramp = 0, origin = \"start\", follower = "
                      "false} is M(s, t) = min(1, t / ramp) beta(sigma) sin(2 pi (t / period "
                      "- sigma / wave_length) + phase) axis, sigma the arc length from the "
                      "end origin (the wave runs away from it), beta the amplitude (N m) or "
                      "a clamped cubic B-spline of its control values over sigma / L; axis "
                      "spatial, or material with follower = true; a rod at rest under it "
                      "has m = M (docs/gallery.md, \"Coming from PyElastica\")"),
    },
    "time": {
        "t_end": Key(real(0.0, True), REQUIRED, "final time"),
        "dt": Key(real(0.0, True), REQUIRED, "time step (also the output interval of the ODE; "
                  "the initial step of adaptive TS)"),
        "scheme": Key(scheme_name, SCHEME, "a name of integrators.schemes (stepper); not "
                      "given, a rod with rotation vectors (geometry.rotations) uses "
                      "generalized-alpha on the rotation group, rho_inf = 0.8"),
        "integrator": Key(choice("stepper", "ts"), "stepper", "stepper | ts (PETSc TS)"),
        "ts_type": Key(ts_type_name, None, "ts: a PETSc TS type of integrators.ts, e.g. "
                       "\"arkimex:4\", \"bdf:3\", \"alpha:0.5\", \"alpha2\" (dynamic torsion); "
                       "default: the scheme's counterpart"),
        "adaptive": Key(boolean, False, "error-controlled time steps: ts (with ts_rtol, "
                        "ts_atol; outputs at each accepted step) or, for a dynamic rod with "
                        "rotation vectors, the stepper (with tolerance; steps within each "
                        "output interval dt, clipped to the output times)"),
        "tolerance": Key(real(0.0, True, 0.5), 1e-3, "stepper, adaptive: local error "
                         "tolerance per step of generalized-alpha on the rotation group "
                         "(displacements to tolerance (L + |x|), rotations to tolerance rad)"),
        "ts_rtol": Key(real(0.0, True, 1.0), TS_RTOL, "ts, adaptive: relative local error "
                       "tolerance"),
        "ts_atol": Key(real(0.0, True, 1.0), TS_ATOL, "ts, adaptive: absolute local error "
                       "tolerance"),
        "predictor": Key(choice("linear", "constant"), PREDICTOR, "stepper: Newton's initial "
                         "guess: \"linear\" (y_n + dt dy/dt_n, extrapolated) | "
                         "\"constant\" (the last state y_n)"),
        "rtol": Key(real(0.0, True, 1.0), NEWTON_RTOL, "relative tolerance (SNES / solve_ivp)"),
        "atol": Key(real(0.0, True, 1.0), None,
                    "absolute tolerance of Newton's residual, in the scene's units of "
                    "forces and couples (and solve_ivp's); not given: unit-free, "
                    f"{NEWTON_FORCE_TOL:g} times the 3-D rod's force scale at each step's "
                    "time (its largest load, at least the force max |A| / L^2 that bends "
                    "it by a radian; docs/rod.md), else (torsion) "
                    f"{NEWTON_ATOL:g}; given: exactly that, above the residual's round-off "
                    "floor (~1e-12 fails at 64 cells) and, 3-D rod, below 1e-6 of the "
                    "scene's forces (`check` warns: Newton would pass its first guess "
                    "unchanged)"),
        "max_step_cuts": Key(integer(0, 30), MAX_STEP_CUTS, "step halvings before giving up"),
        "ode_solution": Key(choice("exact", "scheme"), ODE_SOLUTION,
                            "ODE model: closed form/solve_ivp, or the FE model's scheme"),
    },
    "solver": {
        "preset": Key(choice("default", "native_lu", "jacobian_reuse"), "default",
                      "default (Newton; LU: SuperLU on one rank, MUMPS under MPI; a dynamic "
                      "rod with rotation vectors: its integrator's own) | native_lu (PETSc "
                      "LU, serial only) | "
                      "jacobian_reuse (modified Newton, dynamics with small steps); "
                      "solvers.py"),
        "options": Key(petsc_table, None, "PETSc options (without prefix) over the preset, "
                       "e.g. {snes_max_it = 50, ksp_type = \"preonly\"}"),
    },
    "continuation": {
        "method": Key(choice("load_steps", "arc_length"), "load_steps", R + "quasi-static: "
                      "load_steps (the [time] steps) | arc_length (Riks' arc-length "
                      "continuation in the scene's time, the load factor of the loads linear "
                      "in it, through limit points (snap-through) until time.t_end; a "
                      "snap-through visits times below 0, where a ramp holds 0: a table "
                      "from -1; docs/stability.md)"),
        "parameter": Key(string, None, R + "arc_length: the load whose factor the time is, a "
                         "key of [loads] or an end motion of [boundary] the scene gives (e.g. "
                         "\"loads.end_force\")"),
        "arc_length": Key(real(0.0, True), 0.05, R + "arc_length: the step along the path in "
                          "the norm of (unknowns, load_scale x time)"),
        "load_scale": Key(real(0.0, True), 1.0, R + "arc_length: the weight psi of the time "
                          "against the unknowns in the step's norm"),
        "max_steps": Key(integer(1), 1000, R + "arc_length: the most steps"),
    },
    "stability": {
        "check": Key(boolean, True, R + "quasi-static: after every step the number of negative "
                                    "eigenvalues of the tangent stiffness (column "
                                    "negative_eigenvalues; a warning when it changes; "
                                    "docs/stability.md)"),
        "lowest_eigenvalue": Key(boolean, False, R + "quasi-static, rotation vectors without "
                                              "constraints: also the lowest eigenvalue of "
                                              "K v = lambda G v (G: the lumped L2 metric; column "
                                              "lowest_eigenvalue; SLEPc, ~10-30 ms a step)"),
        "factorisation": Key(choice("banded", "mumps"), "banded", R + "quasi-static: the "
                             "check's factorisation: banded (on one rank without "
                             "constraint multipliers a banded Cholesky first, MUMPS's LDL^T count "
                             "only where K is not positive definite) | mumps (MUMPS's "
                             "LDL^T at every check; docs/stability.md)"),
        "at_bifurcation": Key(choice("switch", "stay"), "switch", R + "quasi-static, rotation "
                              "vectors: when a step makes the equilibrium unstable (the "
                              "count rises), switch to a stable equilibrium at the same "
                              "loads, down the energy from the unstable one perturbed along "
                              "the critical mode (a warning says so) | stay on the computed "
                              "path (docs/stability.md); a rod with Kelvin-Voigt viscosity or "
                              "drag stays: it creeps away from an unstable equilibrium at its "
                              "viscous rate, it does not jump"),
        "follow_unstable": Key(boolean, False, R + "an unstable end state (negative_eigenvalues "
                                              "> 0) is a result: status \"completed\", exit 0 "
                                              "(default: \"completed (unstable equilibrium)\", "
                                              "exit 4)"),
    },
    "outputs": {
        "directory": Key(path_text, "results", "parent folder of the run folders"),
        "every": Key(integer(1), 1, "write rod.bp and animation frames every N steps (and "
                                    "at the end)"),
        "fields": Key(boolean, True, "rod.bp for ParaView (ADIOS2VTXReader): the deformed "
                                     "centre line with directors, strains, natural strains, "
                                     "forces, dissipation (FE models)"),
        "animation": Key(boolean, True, "3-D rod: animation.gif and snapshots.png of the "
                                        "moving centre line (magnified when the motion is "
                                        "small, supports and gravity drawn); torsion: "
                                        "spacetime.png of phi(s, t), u_d(s, t)"),
        "color": Key(choice(*COLOURS), "auto", R + "the field colouring the pictures: "
                     "auto (the evolving natural strain, u_d or v_d, with the largest "
                     "change; u or v if none evolves) | u | v | u_d | v_d (the change since "
                     "t = 0) | n | m (magnitudes) | xi (docs/outputs.md)"),
        "plots": Key(names_or_boolean(*PANELS), True, "histories.png: true (panels chosen "
                     "from the scene's supports and loads), false (none) or a list of "
                     "panels from " + ", ".join(PANELS) + " (docs/outputs.md)"),
        "checkpoint_every": Key(integer(0), 0, "adios4dolfinx checkpoint every N steps (0: off; "
                                               "integrator = \"stepper\" only)"),
        "final_checkpoint": Key(boolean, False, "a checkpoint after the last step too: the "
                                "end state a later run starts from (initial.from_run; "
                                "integrator = \"stepper\" only)"),
        "keep_checkpoints": Key(boolean, False, "keep every checkpoint, not only the last "
                                "(initial.from_time of a later run picks one)"),
        "progress": Key(boolean, True, "tqdm progress bar (rank 0, TTY, not CI)"),
    },
    "contact": {
        "radius": Key(real(0.0, True), None, R + "the rod's radius r: its centre line keeps "
                      "r from an obstacle (needed by [[obstacles]]; default: the radius of "
                      "a circle or tube [section]; docs/contact.md)"),
        "gap": Key(real(0.0, True), None, R + "the barrier's gap delta (< radius): the contact "
                   "force acts where the surfaces are closer than delta and is 0 beyond "
                   "(default radius / 10)"),
        "stiffness": Key(real(0.0, True), None, R + "the barrier's stiffness kappa (default: "
                         "from density / dt^2 and EI / h^4, docs/contact.md)"),
        "slip_tolerance": Key(real(0.0, True), None, R + "friction: the slip velocity eps "
                              "below which friction is smoothed; a rod held by static "
                              "friction creeps slower than eps (default 1e-3 L / t_end)"),
        "self": Key(boolean, False, R + "self-contact: the rod's segments (capsules of "
                    "contact.radius) repel each other through the barrier; neighbours "
                    "closer along the rod than pi (radius + gap) + h are excluded "
                    "(docs/contact.md)"),
        "between_rods": Key(boolean, False, R + "[[rods]]: segments of different rods "
                            "repel each other through the barrier (docs/contact.md)"),
        "self_friction": Key(real(0.0), 0.0, R + "Coulomb friction coefficient mu >= 0 "
                             "between the rod's own segments in contact (contact.self; "
                             "needs density > 0; slip tolerance contact.slip_tolerance)"),
        "between_rods_friction": Key(real(0.0), 0.0, R + "Coulomb friction coefficient mu "
                                     ">= 0 between segments of different rods "
                                     "(contact.between_rods; needs density > 0)"),
        "pair_curve": Key(choice("segments", "smooth"), "segments", R + "the curves whose "
                          "distance the pairs' barrier acts on: segments (the P1 centre "
                          "line's capsules) | smooth (a C^1 Catmull-Rom curve through the "
                          "nodes: a crossing's energy smooth as it moves across a node; no "
                          "friction between segments; docs/contact.md, \"Smooth pairs\")"),
        "obstacle_curve": Key(choice("segments", "smooth"), "smooth", R + "the rod's curves "
                              "whose distance a thin obstacle's barrier acts on (its "
                              "contact on the segments): segments (the P1 chords) | smooth "
                              "(the C^1 Catmull-Rom curve of pair_curve: a contact's energy "
                              "counted once as it passes a node; docs/contact.md, \"Segment "
                              "contact with thin obstacles\")"),
    },
    "obstacles": {
        "shape": Key(choice(*OBSTACLE_SHAPES), REQUIRED, R + "plane (a half-space) | sphere "
                     "| cylinder (finite, solid) | mesh (a triangle surface: a solid if "
                     "closed, else one-sided; docs/contact.md)"),
        "point": Key(vector3(), None, "plane: a point of its surface"),
        "normal": Key(vector3(), None, "plane: the outward normal (the solid is behind it)"),
        "centre": Key(vector3(), None, "sphere, cylinder: the centre; mesh: the offset "
                      "added to its vertices (default 0)"),
        "file": Key(path_text, None, "mesh: an STL (ASCII or binary) or OBJ file, relative "
                    "to the scene's folder; triangles counter-clockwise seen from outside"),
        "vertices": Key(points3, None, "mesh: its vertices [[x, y, z], ...] (with "
                        "triangles, instead of a file)"),
        "triangles": Key(index_triples, None, "mesh: its triangles [[i, j, k], ...] "
                         "(vertex indices from 0, counter-clockwise seen from outside)"),
        "rotation": Key(vector3(), None, "mesh: a rotation vector (radians) applied to the "
                        "vertices before the offset centre"),
        "scale": Key(real(0.0, True), None, "mesh: a factor on the vertices (default 1)"),
        "axis": Key(vector3(), None, "cylinder: the axis direction"),
        "radius": Key(real(0.0, True), None, "sphere, cylinder: the radius"),
        "length": Key(real(0.0, True), None, "cylinder: the length along the axis"),
        "friction": Key(friction_coefficients, 0.0, "Coulomb friction coefficient mu >= 0, "
                        "or {forward, backward, lateral}: directional coefficients relative "
                        "to the rod's axis on the surface (forward: slipping towards the "
                        "rod's end s = L; PyElastica's AnisotropicFrictionalPlane) "
                        "(needs density > 0)"),
        "contact": Key(choice("auto", "nodes", "segments"), "auto", "where the barrier "
                       "acts: nodes (the centre line's nodes) | segments (a sphere's or "
                       "cylinder's: a thin obstacle between two nodes holds the segment; a "
                       "mesh: its nodal law and its sharp convex edges on the segments; "
                       "friction needs rotation vectors) | auto (segments for a sphere or "
                       "cylinder "
                       "of radius R when the longest cell h has h^2 >= 4 (r + gap) (2 R + r "
                       "+ gap), else nodes; docs/contact.md, \"Thin obstacles\")"),
    },
}
REQUIRED_TABLES = ("time",)
# tables written as arrays of tables ([[obstacles]]): each entry checked against the keys
ARRAY_TABLES = ("obstacles",)
RENAMED = {("geometry", "reference_twist"): "initial.natural_twist (u_d at t = 0 is an "
                                            "initial natural strain, not a reference shape)"}


def load_scene(path: str | Path, overrides: dict[str, Any] | None = None,
               files: str | None = None) -> Scene:
    """Read and validate a scene file; every failure is a SceneError.  ``overrides``
    {"table.key": value} (None: remove the key; "table.key.subkey" a key of an inline
    table such as loads.end_force.value) change the file's values first, e.g.
    ``load_scene("scenes/torsion_creep.toml", {"material.variant": "uniform"})``.
    ``files``: the folder of the files the scene names (mesh files, energy modules),
    default the scene file's (a run folder's scene.toml: its scene's, scene_folder)."""
    path = Path(path)
    try:
        raw = read_regular_file(path, SCENE_BYTES)
    except (OSError, ValueError) as err:
        reason = getattr(err, "strerror", None) or err
        raise SceneError(str(path), "", f"cannot read the scene: {reason}") from None
    try:
        text = raw.decode("utf-8-sig")   # a UTF-8 byte-order mark is allowed
    except UnicodeDecodeError as err:
        raise SceneError(str(path), "", f"not UTF-8 text: {err.reason} at byte {err.start}") from None
    return parse_scene(text, source=str(path), default_name=path.stem, overrides=overrides,
                       files=files)


def parse_scene(text: str, source: str = "<string>", default_name: str = "scene",
                overrides: dict[str, Any] | None = None, files: str | None = None) -> Scene:
    """Parse and validate TOML text (with ``overrides``, see load_scene); every failure
    is a SceneError.  ``scene.text`` is the scene as run (the overridden values in)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    except (ValueError, TypeError, RecursionError) as err:   # e.g. lone surrogates
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    if overrides:
        for name, value in overrides.items():
            _override(raw, name, value, source)
        text = f"# {source} with overrides {overrides}\n" + to_toml(raw)
    scene = validate(raw, source, default_name, files)
    scene.text = text
    return scene


def _override(raw: dict, name: str, value: Any, source: str) -> None:
    """raw[table][key]... = value (None: remove it) for name "table.key" or a key inside
    a table's inline table, "table.key.sub" (e.g. loads.end_force.value); a SceneError
    naming the override where the path does not lead through tables (an array of tables
    such as [[rods]], which an override cannot index: edit the file)."""
    table, *path = name.split(".")
    if not path or not all(path):
        raise SceneError(source, name, "an override is named \"table.key\" (or "
                                       "\"table.key.subkey\")")
    if "[" in table:
        raise SceneError(source, name, f"override {name!r}: an override cannot index an "
                                       "array of tables ([[rods]], [[joints]], "
                                       "[[obstacles]]): edit the scene file")
    shadow = shadowing_rod(raw, table, path[0])
    if shadow is not None and value is not None:
        raise SceneError(source, name, f"override {name!r} would not reach {shadow}, "
                                       "which gives its own value: edit the scene file")
    if value is None and table not in raw:
        return
    section, where = raw.setdefault(table, {}), table
    for key in path[:-1]:
        if not isinstance(section, dict):
            break
        if value is None and key not in section:
            return                                  # nothing there to remove
        section, where = section.setdefault(key, {}), f"{where}.{key}"
    if not isinstance(section, dict):
        kind = "an array of tables" if isinstance(section, list) else "not a table"
        raise SceneError(source, name, f"override {name!r}: {where} is {kind}; an override "
                                       "can only change a key of a table: edit the scene "
                                       "file")
    if value is None:
        section.pop(path[-1], None)
    else:
        section[path[-1]] = value


def to_toml(raw: dict) -> str:
    """A scene dict as TOML (tables of keys with inline values), for scene.toml."""
    out = []
    for table, keys in raw.items():
        entries = keys if isinstance(keys, list) else [keys]
        for entry in entries:
            out.append(f"[[{table}]]" if isinstance(keys, list) else f"[{table}]")
            out += [f"{k if k.replace('_', '').isalnum() else toml_value(k)} = "
                    f"{toml_value(v)}" for k, v in entry.items()]
            out.append("")
    return "\n".join(out)


def validate(raw: Any, source: str = "<dict>", default_name: str = "scene",
             files: str | None = None) -> Scene:
    """Validate an already-parsed scene dict; every failure is a SceneError.  A scene
    with ``[[rods]]`` is a rod system (scenes/systems.py)."""
    if not isinstance(raw, dict):
        raise SceneError(source, "", f"a scene must be a table, got {type_name(raw)}")
    if "rods" in raw:
        scene = validate_system(dict(raw), source, default_name,
                                functools.partial(_validate_tables, files=files))
    elif "joints" in raw:
        raise SceneError(source, "joints", "joints join the rods of [[rods]] tables")
    else:
        scene = _validate_tables(raw, source, default_name, files=files)
    if scene.is_rod_material and touching(scene):    # contact at t = 0: the rods placed
        check_initial_contact(scene, initial_centre_lines(scene))
    return scene


def _validate_tables(raw: dict, source: str, default_name: str,
                     joined: bool | None = None, files: str | None = None) -> Scene:
    """The tables of one scene (of one rod; ``joined``: of a rod of [[rods]], None for
    a scene of one rod, whether a joint holds it)."""
    for table in raw:
        if table not in SCHEMA:
            raise SceneError(source, str(table),
                             f"unknown table (known: {', '.join(SCHEMA)})")
    for table in REQUIRED_TABLES:
        if table not in raw:
            raise SceneError(source, table, "missing required table")
    data: dict[str, Any] = {}
    given: dict[str, set[str]] = {}
    for table, keys in SCHEMA.items():
        section = raw.get(table, [] if table in ARRAY_TABLES else {})
        if table in ARRAY_TABLES:
            if not (isinstance(section, list) and all(isinstance(e, dict) for e in section)):
                raise SceneError(source, table, f"must be an array of tables ([[{table}]]), "
                                                f"got {type_name(section)}")
            data[table] = [_table(e, keys, f"{table}[{k}]", source)
                           for k, e in enumerate(section)]
            given[table] = {key for e in section for key in e}
            continue
        if not isinstance(section, dict):
            raise SceneError(source, table, f"must be a table, got {type_name(section)}")
        given[table] = set(section)
        data[table] = _table(section, keys, table, source)
    if data["scene"]["name"] is None:
        data["scene"]["name"] = safe_name(default_name)
    scene = Scene(data, source, given=given, joined=bool(joined),
                  in_system=joined is not None, files=files)
    check_combinations(scene)
    return scene


def _table(section: dict, keys: dict[str, Key], table: str, source: str) -> dict:
    """One table's keys checked, defaults filled in (``table``: its path in errors)."""
    out = {}
    for k in section:
        if (table, k) in RENAMED:
            raise SceneError(source, f"{table}.{k}", f"renamed: use {RENAMED[table, k]}")
        if k not in keys:
            raise SceneError(source, f"{table}.{k}",
                             f"unknown key (known in [{table}]: {', '.join(keys)})")
    for k, spec in keys.items():
        path = f"{table}.{k}"
        if k not in section:
            if spec.default is REQUIRED:
                raise SceneError(source, path, f"missing required key ({spec.doc})")
            out[k] = spec.default
            continue
        try:
            out[k] = spec.check(section[k])
        except BadValue as bad:
            raise SceneError(source, f"{path}.{bad.key}" if bad.key else path,
                             bad.reason) from None
    return out
