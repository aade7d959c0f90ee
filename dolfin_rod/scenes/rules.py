"""Scene rules that involve more than one key (run by :func:`schema.validate` after each
key passed its own check): which model family a key belongs to, time-integration
options, torsion boundary conditions, 3-D rod material, inertia and ends."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from .. import loads as load_histories
from ..integrators.schemes import get_scheme
from ..rod import placement, ring
from ..theory.quaternions import np_quaternion_from_rotation_vector, np_rotation_matrix
from ..rod.rotation_choice import (choose_rotations, rotation_vector_obstacle,
                                   rotations_reason)
from ..checks import (EQUILIBRIUM_NEEDS, MAX_CELL_TURN, is_coordinate_axis,
                      polyline_problem, probed_options, sample_points, slide_axis_problem,
                      spin_free)
from .contact import check_contact_keys
from .physical import apply_physical_input
from .scene import ROD_KEYS, Scene, SceneError
from .values import BadValue, Coefficient, load_entry_point

# the rod's starting state (rod/start.py) in [initial]
START_KEYS = ("position", "orientation", "shape", "velocity", "angular_velocity",
              "rotation_centre", "equilibrium", "acceleration")
TORSION_KEYS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
# keys of one model family only: (table, key) -> the family that reads it
TORSION_ONLY = {("material", k) for k in TORSION_KEYS} | {
    ("geometry", "degree"), ("initial", "natural_twist"), ("loads", "end_torsion")}
ROD_ONLY = {("material", k) for k in ROD_KEYS + ("model", "energy", "constraints",
                                                 "rotational_drag_frame")} | {
    ("section", k) for k in ("shape", "radius", "semi_axes", "sides", "outer_radius",
                             "inner_radius", "shear_factor")} | {
    ("geometry", "reference_curvature"), ("geometry", "reference_stretch"),
    ("geometry", "reference_shape"), ("geometry", "rotations"),
    ("initial", "natural_curvature"), ("initial", "natural_stretch"),
    *(("initial", k) for k in START_KEYS),
    ("boundary", "start_rotation"), ("boundary", "end_displacement"),
    ("boundary", "start_displacement"), ("boundary", "start_slide"),
    ("boundary", "end_slide"), ("boundary", "start_spring"), ("boundary", "end_spring"),
    ("boundary", "start_turn"), ("boundary", "end_turn"),
    ("loads", "distributed_force"), ("loads", "gravity"),
    ("loads", "end_force"), ("loads", "end_couple"), ("loads", "start_force"),
    ("loads", "start_couple"), ("loads", "point_force"), ("loads", "point_couple"),
    ("loads", "muscle"), ("obstacles", "shape")} | {
    ("contact", k) for k in ("radius", "gap", "stiffness", "slip_tolerance", "self",
                             "between_rods", "self_friction", "between_rods_friction",
                             "pair_curve", "obstacle_curve")} | {
    ("stability", k) for k in ("check", "follow_unstable", "lowest_eigenvalue",
                               "at_bifurcation", "factorisation")} | {
    ("continuation", k) for k in ("method", "parameter", "arc_length", "load_scale",
                                  "max_steps")}
# what a continuation parameter may name: a load, or a prescribed end motion
END_MOTIONS = ("start_displacement", "end_displacement", "start_rotation", "end_rotation")
TORSION_DEFAULTS = {"alpha": 1.0, "alpha_d": 1.0, "mu": 0.0, "mu_d": 1.0, "nu": 0.0}


def check_combinations(scene: Scene) -> None:
    """Rules that involve more than one key."""
    rod = scene.is_rod_material
    wrong = ROD_ONLY if not rod else TORSION_ONLY
    for table, key in sorted(wrong):
        if key in scene.given[table]:
            raise scene.error(f"{table}.{key}", (
                "applies to the 3-D rod only; this scene has a torsion material (give "
                "material.stiffness, viscosity for a rod)") if not rod else (
                "applies to the torsion model only; this scene has a 3-D rod material"))
    _check_time(scene)
    _check_from_run(scene)
    if rod:
        _check_rod_material(scene)
        _check_closed(scene)
        _check_rod_ends(scene)
        check_contact_keys(scene, rod_rotations(scene))
        _check_continuation(scene)
        _check_branch_switching(scene)
    else:
        _check_torsion(scene)
    _check_solver_options(scene)
    if scene["time"]["adaptive"] and not adaptive_stepper(scene) \
            and scene["time"]["integrator"] == "stepper":
        raise scene.error("time.adaptive", "the stepper's error-controlled steps are those of "
                                           "generalized-alpha on the rotation group: a dynamic "
                                           "3-D rod with rotation vectors (geometry.rotations); "
                                           "otherwise use integrator = \"ts\"")


def _check_solver_options(scene: Scene) -> None:
    """PETSc reads every option of solver.options and accepts its value (tried on a
    throwaway solver: a bad one failed the run after check said OK); options only this
    package or a later set-up reads (checks.probed_options) load no PETSc."""
    if probed_options(scene["solver"]["options"]):
        from ..fem.solvers import option_problem
        problem = option_problem(scene["solver"]["options"])
        if problem:
            raise scene.error(f"solver.options.{problem[0]}", problem[1])


def adaptive_stepper(scene: Scene) -> bool:
    """The stepper advances the scene with error-controlled steps: time.adaptive, the
    stepper integrator and a dynamic rod with rotation vectors."""
    return bool(scene["time"]["adaptive"] and scene["time"]["integrator"] == "stepper"
                and scene.is_rod_material and scene["material"]["dynamic"]
                and rod_rotations(scene) == "rotation_vector")


def time_stepping(scene: Scene) -> str:
    """One line for ``dolfin-rod check``: the integrator and how its steps are chosen."""
    tim = scene["time"]
    if tim["integrator"] == "ts":
        steps = (f"adaptive (ts_rtol = {tim['ts_rtol']:g}, ts_atol = {tim['ts_atol']:g})"
                 if tim["adaptive"] else f"fixed dt = {tim['dt']:g}")
        return f"PETSc TS, {steps}"
    if adaptive_stepper(scene):
        return (f"stepper, error-controlled steps (time.tolerance = {tim['tolerance']:g}) "
                f"within each output interval dt = {tim['dt']:g}")
    lie = scene.is_rod_material and scene["material"]["dynamic"] \
        and rod_rotations(scene) == "rotation_vector"
    return f"stepper, fixed steps dt = {tim['dt']:g}" + (
        " (time.adaptive is false; setting it true would choose the steps by an error "
        "estimate)" if lie else "")


def _check_branch_switching(scene: Scene) -> None:
    """stability.at_bifurcation = "switch" given for a quasi-static rod with Kelvin-Voigt
    viscosity or drag: its positions move at a viscous rate, so it cannot jump to another
    branch (it creeps away from an unstable equilibrium; by default its path stays)."""
    if "at_bifurcation" not in scene.given["stability"] \
            or scene["stability"]["at_bifurcation"] != "switch" or scene["material"]["dynamic"]:
        return
    key = rate_force_key(scene)
    if key is not None:
        raise scene.error("stability.at_bifurcation", (
            f"\"switch\" jumps to another equilibrium, which a quasi-static rod with "
            f"Kelvin-Voigt viscosity or drag ({key}) cannot do: its positions move at a "
            "viscous rate and creep away from an unstable equilibrium (the time steps "
            "follow that); use \"stay\" or leave the key out"))


def _check_continuation(scene: Scene) -> None:
    """Arc-length continuation: a quasi-static rod, the stepper, and a parameter that is a
    load of the scene (a given key of [loads], or an end motion of [boundary])."""
    con = scene["continuation"]
    if con["method"] != "arc_length":
        return
    if scene["material"]["dynamic"]:
        raise scene.error("continuation.method", "arc_length follows static equilibria: a "
                                                 "quasi-static rod (no material.density)")
    if scene["time"]["integrator"] != "stepper":
        raise scene.error("continuation.method", "arc_length replaces the time steps: "
                                                 "time.integrator = \"stepper\"")
    if not scene.in_system:         # a system's: scenes/systems.py, over all its rods
        check_continuation_parameter(scene, continuation_loads(scene))


def continuation_loads(scene: Scene) -> list[str]:
    """What a continuation parameter may name in a scene (of one rod): its loads and
    end motions."""
    return [f"loads.{k}" for k in sorted(scene.given["loads"])] + \
        [f"boundary.{k}" for k in END_MOTIONS if k in scene.given["boundary"]]


def check_continuation_parameter(scene: Scene, loads: list[str]) -> None:
    """Arc-length continuation's parameter names one of ``loads``."""
    con = scene["continuation"]
    if con["method"] == "arc_length" and con["parameter"] not in loads:
        raise scene.error("continuation.parameter", (
            f"{con['parameter']!r} is not a load of this scene: " if con["parameter"]
            else "arc_length needs the load its parameter scales: ") + (
            f"name one of {', '.join(loads)}" if loads else
            "the scene gives no load or end motion to continue in"))


def _check_time(scene: Scene) -> None:
    tim, given, err = scene["time"], scene.given["time"], scene.error
    ts = tim["integrator"] == "ts"
    for key in ("ts_type", "ts_rtol", "ts_atol"):
        if key in given and not ts:
            raise err(f"time.{key}", "applies to integrator = \"ts\" only")
    for key in ("predictor", "tolerance"):
        if ts and key in given:
            raise err(f"time.{key}", "applies to integrator = \"stepper\" only")
    if "tolerance" in given and not tim["adaptive"]:
        raise err("time.tolerance", "the error tolerance of adaptive steps: set adaptive = true")
    if ts and "ts_type" in given and "scheme" in given:
        raise err("time.scheme", "give either time.scheme (per-step schemes) or time.ts_type "
                                 "(PETSc TS), not both")
    for key in ("ts_rtol", "ts_atol"):
        if key in given and not tim["adaptive"]:
            raise err(f"time.{key}", "an error tolerance of adaptive TS: set adaptive = true")
    if scene["outputs"]["final_checkpoint"] and ts:
        raise err("outputs.final_checkpoint", "checkpoints need integrator = \"stepper\"")
    if scene["outputs"]["checkpoint_every"] and ts:
        raise err("outputs.checkpoint_every", "checkpoints (and --resume) need integrator = "
                                              "\"stepper\": PETSc TS runs the whole interval "
                                              "in one call")
    if tim["dt"] > tim["t_end"]:
        raise err("time.dt", f"must be <= t_end = {tim['t_end']:g}, got {tim['dt']:g}")
    if tim["t_end"] / tim["dt"] > 1e7:
        raise err("time.dt", f"t_end/dt = {tim['t_end'] / tim['dt']:.3g} steps is more than "
                             "10^7")


def _check_from_run(scene: Scene) -> None:
    """A saved state (initial.from_run) is the whole starting state: no other [initial]
    key; from_time picks one of its states.  The run folder itself is checked when the
    scene runs (output/from_run.py)."""
    ini, given, err = scene["initial"], scene.given["initial"], scene.error
    if ini["from_run"] is None:
        for key in sorted(given & {"from_time", "continue_integration"}):
            raise err(f"initial.{key}", "applies to a start from a saved state: give "
                                        "initial.from_run too")
        return
    for key in sorted(given - {"from_run", "from_time", "continue_integration"}):
        raise err(f"initial.{key}", "not with initial.from_run: the starting state, natural "
                                    "strains included, is the previous run's")


def _check_torsion(scene: Scene) -> None:
    """Torsion scenes (dimensionless, Section 5.1)."""
    d, err = scene.data, scene.error
    mat, bnd, lds, tim = d["material"], d["boundary"], d["loads"], d["time"]
    for k in TORSION_KEYS:
        if mat[k] is None:
            mat[k] = Coefficient(constant=TORSION_DEFAULTS[k])
    if mat["variant"] == "uniform" and not mat["mu_d"].is_constant:
        raise err("material.mu_d", "must be a constant for the uniform variant (M_d is one "
                                   "tensor for the whole rod, eq. unatevolunif)")
    if bnd["start"] != "clamped":
        raise err("boundary.start", "the torsion model is clamped at s = 0 (phi(0) = 0)")
    if bnd["end"] not in ("free", "rotation"):
        raise err("boundary.end", "torsion: free (an applied end torsion) or rotation (a "
                                  "prescribed end rotation)")
    if bnd["end_rotation"] is not None and bnd["end_rotation"].is_vector:
        raise err("boundary.end_rotation.value", "torsion: the end rotation Phi is a number")
    if bnd["end"] == "rotation":
        if bnd["end_rotation"] is None:
            raise err("boundary.end_rotation", "missing: boundary.end = \"rotation\" needs "
                                               "the history of the end rotation")
        if lds["end_torsion"] is not None:
            raise err("loads.end_torsion", "an end torsion cannot be applied where the end "
                                           "rotation is prescribed (boundary.end = \"rotation\")")
    elif bnd["end_rotation"] is not None:
        raise err("boundary.end_rotation", "given but boundary.end is \"free\": set "
                                           "boundary.end = \"rotation\"")
    couple = lds["distributed_couple"]
    if couple is not None and (couple.is_vector or couple.follower):
        raise err("loads.distributed_couple." + ("follower" if couple.follower else "value"),
                  "torsion: the couple is value profile(s) history(t), a number")
    if d["geometry"]["length"] != 1.0:
        raise err("geometry.length", "torsion scenes are dimensionless on s in [0, 1] "
                                     "(Section 5.1): length must be 1")
    dynamic = not (mat["nu"].is_constant and mat["nu"].constant == 0.0)
    if dynamic and bnd["end"] == "rotation":
        _check_motions_resolved(scene, ["end_rotation"], "nu > 0")
    if not dynamic and get_scheme(tim["scheme"]).explicit:
        raise err("time.scheme", f"{tim['scheme']} is explicit, but quasi-static torsion "
                                 "(nu = 0) is differential-algebraic: use an implicit scheme")


def _check_motions_resolved(scene: Scene, keys: list[str], inertia: str) -> None:
    """A body with inertia follows a prescribed motion (boundary.<key>) only where the
    time steps resolve it: a jump (a step, at any t0) is refused, and, unless the steps
    adapt (time.adaptive), a ramp, smooth step or table segment shorter than time.dt
    (the end would take an impulse the scheme cannot represent: kinetic energy 9e17
    for a table rising within 1e-10 s, issue 28 item 5)."""
    tim = scene["time"]
    for key in keys:
        spec = scene["boundary"][key]
        fastest, what = (math.inf, "") if spec is None else spec.fastest_change()
        if fastest == 0.0:
            raise scene.error(f"boundary.{key}", f"a step at t = {spec.t0:g} but {inertia}: "
                              "a rod with inertia cannot follow a jump; use type = "
                              "\"smooth_step\" or \"ramp\" lasting at least time.dt")
        if fastest < tim["dt"] and not tim["adaptive"]:
            raise scene.error(f"boundary.{key}.{what}", f"the motion changes within "
                              f"{fastest:g}, faster than time.dt = {tim['dt']:g} resolves "
                              f"({inertia}: the end would take an impulse); let it last "
                              f"at least time.dt, or take time.dt <= {fastest:g}")


def _sampled(value, L: float) -> list[np.ndarray]:
    with np.errstate(over="ignore", invalid="ignore"):     # overflow: checked by callers
        return [np.asarray(value(s) if callable(value) else value, dtype=float)
                for s in sample_points(L)]


def _not_finite(samples: list[np.ndarray], L: float) -> str | None:
    """Why sampled values are unusable (an overflowing polynomial), or None."""
    for si, a in zip(sample_points(L), samples):
        if not np.all(np.isfinite(a)):
            return f"must be finite on [0, {L:g}]; it overflows at s = {si:g}"
    return None


def _check_rod_material(scene: Scene) -> None:
    """3-D rod material: the tensors each model needs, and only those."""
    d, err = scene.data, scene.error
    apply_physical_input(scene)
    mat, L = d["material"], d["geometry"]["length"]
    evolving = mat["model"] == "evolving"
    stiff, visc = mat["stiffness"] or {}, mat["viscosity"] or {}
    needed = {"stiffness": ("A", "B") + (("A_d", "B_d") if evolving else ()),
              "viscosity": ("M_d", "N_d") if evolving else ()}
    for table, have in (("stiffness", stiff), ("viscosity", visc)):
        for k in needed[table]:
            if k not in have:
                raise err(f"material.{table}.{k}", f"missing: the {mat['model']} model needs it")
        for k in have:
            if k in ("A_d", "B_d", "M_d", "N_d") and not evolving:
                raise err(f"material.{table}.{k}", f"a natural-strain tensor; the "
                                                  f"{mat['model']} model has none")
    if mat["model"] == "hyperelastic" and any(k in visc for k in ("M", "N")):
        raise err("material.viscosity", "the hyperelastic model has no viscosity")
    if mat["model"] == "kelvin_voigt" and all(visc.get(k) is None or visc[k].is_zero
                                              for k in ("M", "N")):
        raise err("material.viscosity", "the kelvin_voigt model needs M or N")
    for table, have in (("stiffness", stiff), ("viscosity", visc)):
        for k, t in have.items():
            semidefinite = k in ("M", "N")
            # a constant tensor: its one value (the samples' first, at s = 0)
            samples = [t.terms[0]] if len(t.terms) == 1 else _sampled(t.at, L)
            if _not_finite(samples, L):
                raise err(f"material.{table}.{k}", _not_finite(samples, L))
            for si, a in zip(sample_points(L), samples):
                low = np.linalg.eigvalsh(a).min()
                if low < 0 or (low == 0 and not semidefinite):
                    rule = "positive semidefinite" if semidefinite else "positive definite"
                    raise err(f"material.{table}.{k}", f"must be {rule}; eigenvalue {low:g} "
                                                       f"at s = {si:g}")
    for key in ("variant",):
        if key in scene.given["material"] and not evolving:
            raise err(f"material.{key}", f"the natural strains of the {mat['model']} model "
                                         "do not evolve: drop it")
    for key in ("natural_curvature", "natural_stretch"):
        if d["initial"][key] is not None and not evolving:
            raise err(f"initial.{key}", f"the {mat['model']} model has no natural strains")
    if d["initial"]["natural_stretch"] is not None and \
            mat["constraints"] == "inextensible_unshearable":
        raise err("initial.natural_stretch", "an inextensible, unshearable rod has no "
                                             "natural stretch")
    if d["geometry"]["reference_stretch"][2] <= 0:
        raise err("geometry.reference_stretch", "v_ref,3 must be > 0 (eq. v3pos)")
    _check_rod_inertia(scene)
    _check_rod_start(scene)
    if mat["energy"] is not None:
        try:
            psi = load_entry_point(mat["energy"], scene.folder)
        except BadValue as bad:
            raise err("material.energy", bad.reason) from None
        problem = _start_state_problem(scene, psi)
        if problem:
            raise err("material.energy", problem)


_START_STATE_ANSWERS: dict[tuple, str | None] = {}


def _start_state_problem(scene: Scene, psi) -> str | None:
    """natural_state.start_state_problem at the scene's start: natural strains
    initial.natural_* (default: the reference strains), strains the reference ones.
    Remembered per (psi, strains): its UFL derivatives cost ~1 s, and a fit validates
    one scene per trial with the same energy and start (issue 30)."""
    geo, ini = scene["geometry"], scene["initial"]
    start = (geo["reference_curvature"], geo["reference_stretch"])
    natural = (ini["natural_curvature"] or start[0], ini["natural_stretch"] or start[1])
    key = (psi, *(tuple(map(float, a)) for a in (*natural, *start)))
    if getattr(type(psi), "__hash__", None) is None:      # an unhashable callable object
        return _start_state_answer(psi, natural, start)
    if key not in _START_STATE_ANSWERS:
        _START_STATE_ANSWERS[key] = _start_state_answer(psi, natural, start)
    return _START_STATE_ANSWERS[key]


def _start_state_answer(psi, natural, start) -> str | None:
    from ..theory.natural_state import start_state_problem
    try:
        return start_state_problem(psi, natural, start)
    except Exception as error:      # the user's psi fails on constant strains
        return f"psi cannot be evaluated at the start: {type(error).__name__}: {error}"


def _check_rod_inertia(scene: Scene) -> None:
    mat, lds, err = scene["material"], scene["loads"], scene.error
    L = scene["geometry"]["length"]
    for k in ("density", "drag"):
        c = mat[k] if isinstance(mat[k], Coefficient) else None    # a drag Tensor: checked
        samples = _sampled(c, L) if c is not None else []
        if _not_finite(samples, L):
            raise err(f"material.{k}", _not_finite(samples, L))
        if samples and min(np.min(v) for v in samples) < 0:
            raise err(f"material.{k}", "must be >= 0 on [0, L]")
    if "rotational_drag_frame" in scene.given["material"] and mat["rotational_drag"] is None:
        raise err("material.rotational_drag_frame", "the frame of material.rotational_drag, "
                                                    "which is not given")
    inertia = mat["section_inertia"] or (0.0, 0.0)
    density = mat["density"] or Coefficient(constant=0.0)
    dynamic = not (density.is_constant and density.constant == 0.0)
    if dynamic != (min(inertia) > 0):
        raise err("material.section_inertia", "density and section_inertia (I_11, I_22) must "
                                              "be all > 0 (dynamic) or all 0 (quasi-static)")
    mat["dynamic"] = dynamic
    if dynamic:
        _check_motions_resolved(scene, [f"{end}_{motion}" for end in ("start", "end")
                                        for motion in ("displacement", "rotation")],
                                "density > 0")
    if dynamic and mat["constraints"] != "none":
        raise err("material.constraints", "a dynamic rod (density > 0) with constraint "
                                          "multipliers is an index-3 DAE, which no integrator "
                                          "here solves reliably: use a quasi-static rod or a "
                                          "stiff shear/axial B instead")
    if lds["gravity"] is not None and not dynamic:
        raise err("loads.gravity", "the weight rho_A g needs material.density > 0 (a "
                                   "dynamic rod); quasi-static: use loads.distributed_force")
    if get_scheme(scene["time"]["scheme"]).explicit:    # (DIVERGED_LINEAR_SOLVE at t = 0)
        raise err("time.scheme", f"{scene['time']['scheme']} is explicit, but the 3-D rod is "
                                 "differential-algebraic (its quaternion gauge; quasi-static: "
                                 "also its positions and rotations): use an implicit scheme")
    rod_rotations(scene)


def _check_closed(scene: Scene) -> None:
    """A closed rod (geometry.closed, rod/ring.py): its rules, each error naming the
    scene key; its start is its ring (no initial.shape)."""
    geo, bnd = scene["geometry"], scene["boundary"]
    if not (geo["closed"] or "excess_link" in scene.given["geometry"]):
        return
    if geo["closed"] and "shape" in scene.given["initial"]:
        raise scene.error("initial.shape", "a closed rod starts as its ring (geometry."
                                           "closed, excess_link); give no starting curve")
    motions = {key: {"end": bnd[f"end_{name}"]} if bnd[f"end_{name}"] is not None else None
               for key, name in (("end_displacement", "displacement"),
                                 ("end_rotation", "rotation"), ("end_slide", "slide"),
                                 ("end_springs", "spring"), ("end_turn", "turn"))}
    rod = SimpleNamespace(
        name="rod", closed=geo["closed"], excess_link=geo["excess_link"],
        start=bnd["start"], end=bnd["end"], n_cells=geo["n_cells"], **motions,
        params=placement.Geometry(geo["length"], geo["reference_curvature"],
                                  geo["reference_stretch"], geo["reference_shape"]))
    try:
        ring.check_closed([rod], dynamic=scene["material"]["dynamic"])
    except ValueError as err:
        word = str(err).replace(":", " ").split()[0]
        raise scene.error(ring.KEYS[word], str(err).removeprefix(word).lstrip(": ")) from err


def _check_rod_start(scene: Scene) -> None:
    """The starting state ([initial] START_KEYS) against the rod."""
    ini, err = scene["initial"], scene.error
    if not scene["material"]["dynamic"]:
        for k in ("velocity", "angular_velocity"):
            if ini[k]:
                raise err(f"initial.{k}", "a quasi-static rod (density 0) has no velocities "
                                          "and is in equilibrium at every step")
    if ini["acceleration"] != "balance" and (not scene["material"]["dynamic"]
                                             or rod_rotations(scene) != "rotation_vector"):
        raise err("initial.acceleration", "applies to dynamic rods with rotation-vector "
                                          "unknowns (generalized-alpha starts from the "
                                          "accelerations; quasi-static rods and quaternions' "
                                          "schemes start from the state alone)")
    if ini["equilibrium"] and not scene.joined and not held_at_rest(scene):
        raise err("initial.equilibrium", EQUILIBRIUM_NEEDS)   # a joined rod: its system's
    if ini["rotation_centre"] is not None and ini["angular_velocity"] is None:
        raise err("initial.rotation_centre", "needs initial.angular_velocity (the rigid "
                                             "rotation about it)")
    _check_curve(scene, "initial.shape", ini["shape"])
    geo = scene["geometry"]
    if geo["reference_shape"] is not None:
        strains = [k for k in ("reference_curvature", "reference_stretch")
                   if k in scene.given["geometry"]]
        if strains:
            raise err("geometry.reference_shape", f"the stress-free shape is a curve or the "
                                                  f"helix of geometry.{strains[0]}, not both")
        _check_curve(scene, "geometry.reference_shape", geo["reference_shape"])
        _check_kinked_start(scene)


def _check_kinked_start(scene: Scene) -> None:
    """A rod split at the corners of its stress-free polyline (rod/kinks.py): its rigid
    joints need rotation-vector unknowns (else an error naming geometry.reference_shape),
    and a starting curve keeps its corners (kinks.piece_starts: a polyline with the same
    corners, else an error naming initial.shape); numpy only."""
    from ..rod.kinks import piece_starts, split_placed
    from ..rod.placement import Geometry, PlacedRod
    from ..rod.start import StartingState, curve
    geo, ini = scene["geometry"], scene["initial"]
    split = split_placed(PlacedRod("rod", Geometry(geo["length"], reference_shape=curve(
        geo["reference_shape"])), geo["n_cells"], ("free", "free")))
    if len(split.rods) == 1:
        return
    if rod_rotations(scene) != "rotation_vector":
        raise scene.error("geometry.reference_shape", "a polyline with corners is split there "
                          "into pieces joined rigidly, which needs rotation-vector unknowns "
                          "(geometry.rotations), which this rod does not have: "
                          + rod_rotations_reason(scene))
    if ini["shape"] is not None:      # (where the rod starts and its velocities: no matter)
        try:
            piece_starts(StartingState(shape=curve(ini["shape"])), split)
        except ValueError as bad:
            raise scene.error("initial.shape", str(bad).removeprefix("start.shape: ")) \
                from None


def held_at_rest(scene: Scene) -> bool:
    """Whether something holds the rod of ``scene`` against rigid motions, as its static
    equilibrium (initial.equilibrium) needs: an end support, rotation or spring, or
    obstacles to rest on (the model's rod/initial_state.supported)."""
    bnd = scene["boundary"]
    return bool(scene["obstacles"]) or any(
        bnd[end] != "free" or bnd[f"{end}_rotation"] or bnd[f"{end}_spring"]
        for end in ("start", "end"))


def _check_curve(scene: Scene, key: str, shape: dict | None) -> None:
    """A polyline (rod/start.py) of the rod's length, or an error naming ``key``."""
    if shape is not None and shape["type"] == "polyline":
        problem = polyline_problem(shape["points"], shape["rest_arc_length"], shape["normal"],
                                   scene["geometry"]["length"])
        if problem:
            raise scene.error(f"{key}.{problem[0]}", problem[1])


def rod_rotations(scene: Scene) -> str:
    """The rod's rotation unknowns (rod/discretisation.py) for geometry.rotations: "auto"
    takes rotation vectors (6 unknowns per node) for the local variant, no constraint and
    the stepper integrator: a dynamic rod with time.scheme not given or a
    generalized_alpha (on the rotation group), or a quasi-static one without Kelvin-Voigt
    viscosity and drag, with any scheme (validation.choose_rotations); quaternions
    otherwise."""
    return _rotations(scene, choose_rotations)


def rod_rotations_reason(scene: Scene) -> str:
    """rod_rotations and why, in plain words (``dolfin-rod check``)."""
    return _rotations(scene, rotations_reason)


def _rotations(scene: Scene, choose) -> str:
    """``choose`` (choose_rotations or rotations_reason) of the scene's rotation inputs."""
    tim, mat = scene["time"], scene["material"]
    lie = tim["integrator"] == "stepper" and (
        not mat["dynamic"] or "scheme" not in scene.given["time"]
        or tim["scheme"].startswith("generalized_alpha"))
    motions = [scene["boundary"][f"{end}_rotation"] for end in ("start", "end")]
    rotation_jumps = not mat["dynamic"] and any(spec is not None and spec.is_vector and any(
        load_histories.jumps(spec.build(i)) for i in range(3)) for spec in motions)
    obstacle = rotation_obstacle(scene)[0]
    try:
        return choose(scene["geometry"]["rotations"], obstacle, lie_integrator=lie,
                      rotation_jumps=rotation_jumps)
    except ValueError as err:
        key = "geometry.rotations" if obstacle else "time.scheme"
        raise scene.error(key, str(err)) from err


def rotation_obstacle(scene: Scene) -> tuple[str | None, str]:
    """Why the rod of ``scene`` cannot have rotation-vector unknowns (rotation_choice.
    rotation_vector_obstacle of its material; None if it can) and the key that says so."""
    mat = scene["material"]
    constraint = None if mat["constraints"] == "none" else mat["constraints"]
    rates = rate_force_key(scene)
    why = rotation_vector_obstacle(mat["dynamic"], mat["variant"], constraint,
                                   rate_dependent=rates is not None)
    key = ("material.variant" if mat["variant"] != "local" else "material.constraints"
           if constraint else rates)
    return why, key


def rate_force_key(scene: Scene) -> str | None:
    """The key of the scene's forces of the rates of positions and rotations (Kelvin-Voigt
    viscosity M, N: "material.viscosity"; drag: "material.drag"), None if it has none."""
    mat = scene["material"]
    visc = mat["viscosity"] or {}
    if any(k in visc and not visc[k].is_zero for k in ("M", "N")):
        return "material.viscosity"
    drag = not (mat["drag"] is None or mat["drag"].is_zero) \
        or not (mat["rotational_drag"] is None or mat["rotational_drag"].is_zero)
    return "material.drag" if drag else None


def _check_turns_resolved(scene: Scene) -> None:
    """The prescribed end rotations turn one end against the other by at most what
    geometry.n_cells cells represent: each cell's relative rotation stays below
    checks.MAX_CELL_TURN (100 rad on 4 cells wrapped silently to a wrong energy and a
    couple of the wrong sign, issue 28 item 4; runs check it after every step, for
    couples too: RodModel.check_cell_turns).  The
    largest angle is taken at the histories' breakpoints up to t_end (linear or monotone
    in between)."""
    bnd, n = scene["boundary"], scene["geometry"]["n_cells"]
    specs = {end: bnd[f"{end}_rotation"] for end in ("start", "end")}
    if specs["end"] is None and specs["start"] is None:
        return
    t_end = scene["time"]["t_end"]
    times = sorted({0.0, t_end} | {t for spec in specs.values() if spec is not None
                                   for t in spec.breakpoints() if 0.0 <= t <= t_end})
    zero = lambda t: np.zeros(3)                                     # noqa: E731
    start, end = (spec.vector() if spec is not None else zero for spec in specs.values())
    angle = max(float(np.linalg.norm(end(t) - start(t))) for t in times)
    if angle >= n * MAX_CELL_TURN:
        key = "end" if specs["end"] is not None else "start"
        raise scene.error(f"boundary.{key}_rotation", f"turns one end against the other by "
                          f"{angle:.4g} rad, more than geometry.n_cells = {n} cells "
                          "represent (each cell's relative rotation must stay below "
                          f"{MAX_CELL_TURN:g} rad): take n_cells >= "
                          f"{math.floor(angle / MAX_CELL_TURN) + 1}")


def _spring(scene: Scene, end: str, position_held: bool, rotation_held: bool) -> dict:
    """The spring table of an end (boundary.<end>_spring, {} if none) after its checks:
    each part where that motion is free."""
    bnd = scene["boundary"]
    spring = bnd[f"{end}_spring"] or {}
    for part, held, what in (("translational", position_held, "position"),
                             ("rotational", rotation_held, "rotation")):
        if np.any(spring.get(part, 0.0)) and held:
            raise scene.error(f"boundary.{end}_spring.{part}", f"the end's {what} is held or "
                                                               "prescribed: the support "
                                                               "takes the spring's place")
    return spring


def _slide_axis(scene: Scene, end: str):
    """The slide axis of an end (boundary.<end>_slide) after its checks, or None."""
    bnd, key = scene["boundary"], f"boundary.{end}_slide"
    axis = bnd[f"{end}_slide"]
    if axis is None:
        return None
    if bnd[end] not in ("clamped", "pinned"):
        raise scene.error(key, f"boundary.{end} is {bnd[end]!r}: only a clamped or pinned "
                               "end slides in its support")
    problem = slide_axis_problem(axis)
    if problem:
        raise scene.error(key, problem)
    motion = bnd[f"{end}_displacement"]
    if motion is not None and not is_coordinate_axis(axis):
        raise scene.error(f"boundary.{end}_displacement", f"the end slides along {list(axis)} "
                                                          f"({key}), off the coordinate axes: "
                                                          "its motion across that axis cannot "
                                                          "be prescribed (only across +-e_i)")
    if motion is not None and motion.is_vector and _along(motion, axis):
        raise scene.error(f"boundary.{end}_displacement", f"the end slides freely along "
                                                          f"{list(axis)} ({key}): prescribe "
                                                          "its motion across that axis only")
    if not is_coordinate_axis(axis) and scene["time"]["integrator"] == "ts":
        raise scene.error(key, "an axis off the coordinate axes is a one-node link that "
                               "PETSc TS does not hold: take time.integrator = 'stepper'")
    return np.asarray(axis)


def _turn_axis(scene: Scene, end: str):
    """The axis a clamped end turns about (boundary.<end>_turn) after its checks, or None."""
    bnd, key = scene["boundary"], f"boundary.{end}_turn"
    axis = bnd[f"{end}_turn"]
    if axis is None:
        return None
    if bnd[end] != "clamped":
        raise scene.error(key, f"boundary.{end} is {bnd[end]!r}: only a clamped end turns "
                               "in its support")
    slide = bnd[f"{end}_slide"]
    problem = slide_axis_problem(axis) or (
        "must equal boundary." + end + "_slide" if slide is not None and slide != axis else None)
    if problem:
        raise scene.error(key, problem)
    if bnd[f"{end}_rotation"] is not None:
        raise scene.error(f"boundary.{end}_rotation", f"the end turns freely ({key}): its "
                                                      "rotation cannot also be prescribed")
    if not is_coordinate_axis(axis) and rod_rotations(scene) != "rotation_vector":
        raise scene.error(key, "a turn about an axis off the coordinate axes needs "
                               "rotation-vector unknowns (geometry.rotations; with "
                               "quaternions it holds q in a plane, not on a line), which "
                               "this rod does not have: " + rod_rotations_reason(scene))
    return np.asarray(axis)


def _held_directions(held: bool, free_axis) -> np.ndarray:
    """Rows spanning the directions a support holds: all three, or those across the
    axis it slides along or turns about."""
    if not held:
        return np.zeros((3, 3))
    return np.eye(3) if free_axis is None else np.eye(3) - np.outer(free_axis, free_axis)


def _rigid_motions_held(scene: Scene, held: list) -> bool:
    """Whether the two ends' supports ((position, rotation) directions held at the start
    and the end: _held_directions) hold every rigid motion (translation c, rotation w) of
    a rod whose start shape is its stress-free helix of reference strains (straight by
    default): an end at x moves by c + w x x, so the six columns (c, w) must have rank 6
    (a simply supported beam: a hinge at the start, a roller sliding along the axis at
    the end).  A rod pinned at both ends with no end rotation, turn or spring has its
    spin about d3 held at s = 0 by the model (rod/boundary_conditions.spin_free: the
    pinned-pinned column).  Other start shapes: False (the supports must then hold one
    end fully)."""
    geo, bnd = scene["geometry"], scene["boundary"]
    if "shape" in scene.given["initial"] or geo["reference_shape"] is not None:
        return False
    r, _ = placement.helix(np.array([0.0, geo["length"]]), geo["reference_curvature"],
                           geo["reference_stretch"])
    turn = np_rotation_matrix(np_quaternion_from_rotation_vector(
        np.asarray(scene["initial"]["orientation"] or (0.0, 0.0, 0.0), float)))
    if spin_free((bnd["start"], bnd["end"]), *(
            {end: bnd[f"{end}_{key}"] for end in ("start", "end") if bnd[f"{end}_{key}"]}
            for key in ("rotation", "turn", "spring"))):
        d3 = turn[:, 2]                 # the start's d3 (the helix starts with R = I)
        held = [(held[0][0], held[0][1] + np.outer(d3, d3)), held[1]]
    rows = []          # x in units of the length: the columns of w scaled as those of c
    for (position, rotation), x in zip(held, (np.zeros(3), turn @ r[-1] / geo["length"])):
        w_cross_x = np.cross(np.eye(3), x).T          # column j: e_j x x
        rows += [np.hstack([position, position @ w_cross_x]),
                 np.hstack([np.zeros((3, 3)), rotation])]
    return np.linalg.matrix_rank(np.vstack(rows)) == 6


def _along(spec, axis) -> bool:
    """Whether a vector history has a component along the axis."""
    values = np.array(spec.values if spec.type == "table" else (spec.value,), float)
    return bool(np.any(values @ np.asarray(axis) != 0.0))


def _check_rod_ends(scene: Scene) -> None:
    """Supports, prescribed end motions and end loads of the 3-D rod."""
    bnd, lds, err = scene["boundary"], scene["loads"], scene.error
    fixed_x, fixed_q, held = [], [], []
    for end in ("start", "end"):
        kind = bnd[end]
        if kind == "rotation":
            raise err(f"boundary.{end}", "3-D rod: clamped, pinned or free; a prescribed "
                                         f"rotation is boundary.{end}_rotation")
        for motion in ("displacement", "rotation"):
            spec = bnd[f"{end}_{motion}"]
            if spec is not None and not spec.is_vector:
                raise err(f"boundary.{end}_{motion}.value", "3-D rod: a vector [x, y, z]")
            if spec is not None and spec.type == "step" and spec.t0 > 0 and \
                    scene["material"]["dynamic"]:
                raise err(f"boundary.{end}_{motion}", f"a step at t0 = {spec.t0:g}, but a rod "
                                                      "with inertia cannot follow a jump of its "
                                                      "end: use type = \"smooth_step\" or "
                                                      "\"ramp\" (with t0)")
        axis, turn = _slide_axis(scene, end), _turn_axis(scene, end)
        x = kind in ("clamped", "pinned") or bnd[f"{end}_displacement"] is not None
        q = kind == "clamped" or bnd[f"{end}_rotation"] is not None
        spring = _spring(scene, end, x and axis is None, q and turn is None)
        fixed_x.append((x and axis is None) or np.all(spring.get("translational", 0.0)))
        fixed_q.append((q and turn is None) or np.all(spring.get("rotational", 0.0)))
        held.append((_held_directions(x, axis) if x else
                     np.diag(np.broadcast_to(spring.get("translational", 0.0), 3) > 0) * 1.0,
                     _held_directions(q, turn) if q else np.eye(3) * fixed_q[-1]))
        for load, fixed, what in (("force", x, "position"), ("couple", q, "rotation")):
            spec = lds[f"{end}_{load}"]
            if spec is None:
                continue
            if not spec.is_vector:
                raise err(f"loads.{end}_{load}.value", "3-D rod: a vector value = [x, y, z] "
                                                       "(or a table of 3-vectors)")
            free_axis = axis if load == "force" else turn
            if free_axis is not None:
                if spec.follower:
                    how = "slides along" if load == "force" else "turns about"
                    raise err(f"loads.{end}_{load}", f"the end {how} {list(free_axis)} "
                                                     f"(boundary.{end}_"
                                                     f"{'slide' if load == 'force' else 'turn'}"
                                                     f"): only a dead {load} acts on it (its "
                                                     "part along the axis; the support takes "
                                                     "the rest)")
                continue
            if fixed:
                raise err(f"loads.{end}_{load}", f"acts where the {what} is prescribed "
                                                 f"(boundary.{end} = {kind!r}): the support "
                                                 "takes it")
    for k in ("distributed_force", "distributed_couple", "point_force", "point_couple"):
        if lds[k] is not None and not lds[k].is_vector:
            raise err(f"loads.{k}.value", "3-D rod: a vector value = [x, y, z] (or a table "
                                          "of 3-vectors)")
    length = scene["geometry"]["length"]
    for k in ("point_force", "point_couple"):
        if lds[k] is not None and not 0.0 <= lds[k].s <= length:
            raise err(f"loads.{k}.s", f"{lds[k].s:g} is not on the rod: 0 <= s <= "
                                      f"geometry.length = {length:g}")
    _check_turns_resolved(scene)
    if not scene["material"]["dynamic"] and not scene.joined and \
            not (any(fixed_x) and any(fixed_q)) and not _rigid_motions_held(scene, held):
        raise err("boundary.start", "a quasi-static rod needs supports that hold every "
                                    "rigid motion: a fixed position and a fixed rotation "
                                    "somewhere (e.g. start = \"clamped\"), or a hinge at one "
                                    "end and a roller at the other (boundary.start_turn, "
                                    "end_slide); rigid motions are free otherwise")


# loads and end motions a buckling analysis scales ([loads] and [boundary] keys)
LOAD_KEYS = ("end_force", "end_couple", "start_force", "start_couple", "distributed_force",
             "distributed_couple", "point_force", "point_couple")
MOTION_KEYS = ("end_rotation", "start_rotation", "end_displacement", "start_displacement")


def _changes_at_the_end(spec, t: float) -> bool:
    """Whether a load or motion history changes over the step before t that buckling
    takes for the loads' rate (analysis/buckling.py: a backward difference over
    RELATIVE_STEP t)."""
    from ..analysis.buckling import RELATIVE_STEP
    histories = [spec.build(i) for i in range(3)] if spec.is_vector else [spec.build()]
    return any(np.any(np.asarray(h(t)) != np.asarray(h(t - RELATIVE_STEP * t)))
               for h in histories)


def analysis_problem(scene: Scene, kind: str) -> None:
    """Refuse (SceneError naming the key) a scene that ``dolfin-rod buckle`` ("buckle")
    or ``modes`` ("modes") cannot analyse, before any work: a 3-D rod (or rods with
    joints), either rotation unknowns; buckling a quasi-static one without constraints
    with a load or end motion, modes one with mass (docs/stability.md)."""
    if not scene.is_rod_material:
        raise scene.error("material", f"{kind}: a 3-D rod (material.stiffness, or a "
                                      "[section] with material.youngs_modulus)")
    mat = scene["material"]
    if kind == "modes" and not mat["dynamic"]:
        raise scene.error("material.density", "modes: the rod's mass (material.density "
                                               "> 0, and material.section_inertia)")
    if kind == "buckle":
        if mat["dynamic"]:
            raise scene.error("material.density", "buckle: a quasi-static rod (no "
                                                   "density); for a dynamic one: modes")
        specs = [part[table][k] for part in [scene, *(rod.scene for rod in scene.rods)]
                 for table, keys in (("loads", LOAD_KEYS), ("boundary", MOTION_KEYS))
                 for k in keys if part[table][k] is not None]
        if not specs:
            raise scene.error("loads", "buckle: a load (loads.end_force, ...) or an end "
                                       "motion (boundary.end_rotation, ...) to scale")
        if not any(map(_changes_at_the_end, specs, [scene["time"]["t_end"]] * len(specs))):
            raise scene.error("loads", "buckle: the loads and prescribed motions do not "
                                       f"change at time.t_end = {scene['time']['t_end']:g} "
                                       "(nothing to scale: ramp them, e.g. type = \"ramp\" "
                                       "up to t_end)")
        if mat["constraints"] != "none":
            raise scene.error("material.constraints", "buckle: a rod without constraints "
                                                      "(their multipliers' rates are not "
                                                      "in the analysis)")
