"""Input checks shared by the modules (errors name the parameter and the rule), and the
defaults a scene key and the API argument of the same quantity share."""

from __future__ import annotations

import functools
import math
import numbers
import re
import warnings

import numpy as np


def finite(name: str, value: float) -> float:
    """``value`` as a float; TypeError if not a real number, ValueError if not finite."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def positive(name: str, value: float) -> float:
    """``value`` as a float, or ValueError unless it is finite and > 0."""
    x = finite(name, value)
    if not x > 0.0:
        raise ValueError(f"{name} must be > 0, got {x}")
    return x


def nonnegative(name: str, value: float) -> float:
    """``value`` as a float, or ValueError unless it is finite and >= 0."""
    x = finite(name, value)
    if not x >= 0.0:
        raise ValueError(f"{name} must be >= 0, got {x}")
    return x


ENDS = ("start", "end")      # a rod's ends: s = 0 and s = L (the scene's boundary.start/end)
OLD_END_NAMES = {"left": "start", "right": "end"}    # their names before (deprecated)
END_KEYED = ("end_displacement", "end_rotation", "end_slide", "end_springs", "end_turn")


def end_name(owner: str, name, stacklevel: int):
    """The end ``name`` ("start" or "end"); the deprecated "left" and "right" as those,
    with a DeprecationWarning naming the new one at the caller ``stacklevel`` frames up
    (from the function that calls this one); anything else as it is (for the checks)."""
    if isinstance(name, str) and name in OLD_END_NAMES:
        warnings.warn(f"{owner}: the end {name!r} is deprecated and goes in the next "
                      f"release: use {OLD_END_NAMES[name]!r} (the scene's name: s = "
                      f"{'0' if name == 'left' else 'L'})", DeprecationWarning,
                      stacklevel=stacklevel + 1)
        return OLD_END_NAMES[name]
    return name


# a time-series column of an end before the ends took the scene's names (runs before
# this release, users' lists of columns): reaction_force_left_x is reaction_force_start_x
_OLD_END_COLUMN = re.compile(r"(reaction_(?:force|couple))_(left|right)_([xyz])$")


def new_column(name: str) -> str:
    """The time-series column ``name`` as named now (an old end column renamed)."""
    return _OLD_END_COLUMN.sub(lambda m: f"{m[1]}_{OLD_END_NAMES[m[2]]}_{m[3]}", name)


def end_keyed(owner: str, given: dict, stacklevel: int) -> dict:
    """``given`` {keyword: value} with the END_KEYED dicts' keys as end_name gives them
    (loops, not comprehensions: the frames of the warning's line)."""
    out = dict(given)
    for key in END_KEYED:
        if isinstance(given.get(key), dict):
            out[key] = {}
            for end, value in given[key].items():
                out[key][end_name(f"{owner} {key}", end, stacklevel + 1)] = value
    return out


def deprecated_names(owner: str, given: dict, renamed: dict[str, str],
                     stacklevel: int = 3) -> dict:
    """``given`` {old name: value}, the keywords of ``owner`` whose names changed to the
    scene's (docs/rod.md, "One vocabulary"): a DeprecationWarning for each, naming its
    new name ``renamed[old]`` (the old names go in the next release); TypeError for a
    name that never was a keyword.  The warning's line is the caller's (``stacklevel``
    frames up: that of the function that calls this one)."""
    for old in given:
        if old not in renamed:
            raise TypeError(f"{owner}() got an unexpected keyword argument {old!r}")
        warnings.warn(f"{owner}: {old!r} is deprecated and goes in the next release: use "
                      f"{renamed[old]} (the scene key's name)", DeprecationWarning,
                      stacklevel=stacklevel)
    return given


def old_keywords(owner: str, renamed: dict[str, str], translate):
    """A decorator of ``owner`` (a function or an __init__) that also takes the deprecated
    keywords of ``renamed`` {old: new} (``deprecated_names``): ``translate`` turns them,
    {old: value}, into the new ones; TypeError if a new one is given too."""
    def decorate(func):
        @functools.wraps(func)
        def accepting(*args, **kwargs):
            old = deprecated_names(owner, {k: kwargs.pop(k) for k in list(kwargs)
                                           if k in renamed}, renamed)
            new = translate(old) if old else {}
            for name in set(new) & set(kwargs):
                raise TypeError(f"{owner}: give {name} or the deprecated "
                                f"{', '.join(old)}, not both")
            return func(*args, **kwargs, **new)
        return accepting
    return decorate

# The shortest rod: DOLFINx refuses intervals shorter than machine epsilon, and below
# this the solvers' absolute tolerances exceed the rod's residuals (a rod of 2 cells
# and length 1e-12 gives the tip displacement of length 1 scaled by 1e-12; 1e-15 fails).
MIN_LENGTH = 1e-12


def rod_length(value: float) -> float:
    """The rod's length as a float, or ValueError naming the rule."""
    x = finite("length", value)
    if not x >= MIN_LENGTH:
        raise ValueError(f"length must be >= {MIN_LENGTH:g} (choose a smaller length "
                         f"unit), got {x:g}")
    return x


# -- Defaults: a scene key's default (scenes/schema.py) and the default of the API
# argument for the same quantity are one value, here (below every layer that uses them;
# tests/test_architecture.py compares every pair).
N_CELLS = 32                # geometry.n_cells: RodModel, Rod, TorsionModel
DEGREE = 1                  # geometry.degree: TorsionModel
ROTATION_UNKNOWNS = "auto"  # geometry.rotations: RodModel, RodSystem
ROD_MODEL = "evolving"      # material.model: RodModel, RodSystem
VARIANT = "local"           # material.variant: RodModel, RodSystem, TorsionModel
MAX_STEP_CUTS = 6           # time.max_step_cuts: TimeStepper, SchemeStepper,
                            #   LieGeneralizedAlpha (max_cuts)
PREDICTOR = "linear"        # time.predictor: TimeStepper, SchemeStepper
SCHEME = "bdf2"             # time.scheme: SchemeStepper (a first-order form: the quaternion
                            #   rod, torsion) when none is named, OdeTime
NEWTON_RTOL = 1e-10         # time.rtol: BlockSNES's snes_rtol
NEWTON_ATOL = 1e-10         # BlockSNES's snes_atol for a problem without a force scale
                            #   (the torsion model; above its residual's round-off floor)
                            #   and OdeTime's solve_ivp atol (time.atol not given)
NEWTON_FORCE_TOL = 1e-10    # time.atol not given: a rod's snes_atol is this times its
                            #   force scale at the solve's time (rod/force_scale.py)
NEWTON_FORCE_CAP = 1e-3     # Newton's relative test accepts no residual above this times
                            #   the force scale (solvers.relative_tolerance: a dynamic
                            #   step's first residual dominated by stiff rows or a barrier)
TS_RTOL, TS_ATOL = 1e-6, 1e-8   # time.ts_rtol, time.ts_atol: TSIntegrator
# solver options read only when a solver is set up or solves (block Jacobi's sub-solvers,
# the factorisation packages, viewers) and this package's own: not probed on PETSc
LATE_OPTIONS = ("sub_", "mat_", "jacobian_reuse_ratio", "linesearch_fallback")
ODE_SOLUTION = "exact"      # time.ode_solution: OdeTime

# The largest rotation of a cell's end node against its start node that the rod's
# rotation interpolation represents (issue 28 item 4): the cell's strain times its
# length is 2 tan(theta/2) for rotation vectors (rod/rotation_vector.py) and 4 tan(theta/4)
# for quaternions (the P1 interpolant at the midpoint), turns of 3.11 and 2.19 rad at
# theta = 2, below pi; beyond, the strain blows up (rotation vectors: pi is never
# reached, the rod stiffens) or the turn wraps to a wrong, smaller one.
MAX_CELL_TURN = 2.0

# Under MPI a rank with fewer cells has no cell at all (DOLFINx's reshape errors) or its
# Dirichlet dof is a ghost of the mixed space (assembly.py); with 2 it runs.
MIN_CELLS_PER_RANK = 2


def check_n_cells(n_cells, ranks: int = 1) -> int:
    """n_cells as an int; ValueError unless it is a positive integer and, on more than
    one MPI rank, gives every rank MIN_CELLS_PER_RANK cells."""
    if not (isinstance(n_cells, (int, np.integer)) and n_cells >= 1):
        raise ValueError(f"n_cells must be a positive integer, got {n_cells!r}")
    if ranks > 1 and n_cells < MIN_CELLS_PER_RANK * ranks:
        fit = max(1, n_cells // MIN_CELLS_PER_RANK)
        raise ValueError(f"n_cells = {n_cells} is too few for {ranks} MPI ranks: each rank "
                         f"needs {MIN_CELLS_PER_RANK} cells, so n_cells >= "
                         f"{MIN_CELLS_PER_RANK * ranks} (or run on {fit} rank"
                         f"{'s' if fit > 1 else ''})")
    return int(n_cells)


# The largest input files read: a scene (TOML, tables of load histories included) and
# fit data (CSV: 1e6 rows of three numbers are ~60 MB)
SCENE_BYTES = 16 * 2**20
DATA_BYTES = 512 * 2**20


def read_regular_file(path, limit: int) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes; ValueError naming the
    rule for anything else (a device such as /dev/zero read until memory ran out, a
    pipe, a folder, a larger file); OSError if it cannot be read."""
    import os
    import stat
    if not stat.S_ISREG(os.stat(path).st_mode):
        raise ValueError("not a regular file (a device, pipe or folder)")
    with open(path, "rb") as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"larger than {limit // 2**20} MiB, the bound for this input")
    return data


# Coefficients given as functions of s are checked at this many equally spaced points
# (rod, torsion and the scene schema alike).
COEFFICIENT_SAMPLES = 257


def sample_points(length: float = 1.0) -> np.ndarray:
    """The points s in [0, length] where coefficient functions are checked."""
    return np.linspace(0.0, length, COEFFICIENT_SAMPLES)


def profile_violation(values: np.ndarray, s: np.ndarray, strict: bool) -> str | None:
    """Why a coefficient sampled at s breaks its rule (finite and > 0 if strict, else
    >= 0 and either > 0 everywhere or 0 everywhere), or None."""
    values = np.broadcast_to(np.asarray(values, dtype=float), s.shape)
    bad = ~np.isfinite(values) | ((values <= 0) if strict else (values < 0))
    if bad.any():
        rule = "> 0" if strict else ">= 0"
        return (f"must be {rule} on [0, {s[-1]:g}]; got {values[bad][0]:g} "
                f"at s = {s[bad][0]:g}")
    if not strict and (values == 0).any() and (values > 0).any():
        return "must be either > 0 everywhere or 0 everywhere"
    return None


def slide_axis_problem(axis) -> str | None:
    """Why ``axis`` cannot be a slide or turning axis (None if it can): not a finite unit
    3-vector (any direction: a coordinate axis holds the other two components by
    Dirichlet conditions, another one by a one-node link, fem/multipoint.NodeLine)."""
    a = np.asarray(axis, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        return f"must be a finite 3-vector, got {axis!r}"
    if abs(np.linalg.norm(a) - 1.0) > 1e-12:
        return f"must be a unit vector, got {a.tolist()} (length {np.linalg.norm(a):.6g})"
    return None


def is_coordinate_axis(axis) -> bool:
    """+-e_1, +-e_2 or +-e_3 (a slide_axis_problem-free axis)."""
    return int(np.count_nonzero(np.asarray(axis, dtype=float))) == 1


# A start in static equilibrium (rod/start.py) needs something that holds the rod against
# rigid motions (rod/initial_state.py settles it, in pseudo-time where one solve fails).
EQUILIBRIUM_NEEDS = ("the static problem needs a supported end (clamped, pinned, a "
                     "prescribed end rotation or an end spring) or obstacles to rest on: "
                     "nothing holds a free rod against its loads")
# How a dynamic rod's accelerations start (initial.acceleration, StartingState.acceleration,
# SecondOrderProblem.starting_accelerations): solved from the balance laws at t0 (friction
# read at the first step's slip), or zero (a state known to be at rest).
STARTING_ACCELERATIONS = ("balance", "zero")


def one_of(name: str, value, options: tuple) -> None:
    """ValueError naming ``name`` unless ``value`` is one of ``options``."""
    if value not in options:
        raise ValueError(f"{name} must be one of {', '.join(options)}, got {value!r}")


# A starting polyline's length against the rod's (rod/start.py; a rod of 1 m: 1 um).
LENGTH_RTOL = 1e-6


FOLD = 1e-4            # rad: a polyline turning by more than pi - FOLD folds back


def polyline_problem(points, rest_arc_length, normal, length: float) -> tuple[str, str] | None:
    """(key, reason) for a starting polyline (rod/start.Polyline) that does not fit a rod
    of ``length``, key one of "points", "rest_arc_length", "normal"; else None."""
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1:] != (3,) or len(points) < 2 \
            or not np.isfinite(points).all():
        return "points", "at least two finite points [x, y, z]"
    chords = np.diff(points, axis=0)
    if np.any(np.linalg.norm(chords, axis=1) == 0):
        return "points", "two consecutive points coincide"
    unit = chords / np.linalg.norm(chords, axis=1)[:, None]
    back = np.flatnonzero(1.0 + np.einsum("ij,ij->i", unit[:-1], unit[1:]) <= FOLD ** 2 / 2)
    if len(back):       # parallel transport (start.py) divides by 1 + cos(turn) there
        return "points", (f"turns back on itself at point {back[0] + 1} "
                          f"({', '.join(f'{v:g}' for v in points[back[0] + 1])}: by 180 degrees, within {FOLD:g} "
                          "rad): the frame carried across the fold is undefined; a "
                          "hairpin needs a segment across its bend")
    if rest_arc_length is None:
        key, what = "points", "polyline's length"
        arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(chords, axis=1))))
    else:
        key, what = "rest_arc_length", "last rest arc length"
        arc = np.asarray(rest_arc_length, dtype=float)
        if arc.shape != (len(points),) or arc[0] != 0 or np.any(np.diff(arc) <= 0):
            return key, f"one value per point ({len(points)}), from 0, increasing"
    if abs(arc[-1] - length) > LENGTH_RTOL * length:
        return key, (f"the {what} {arc[-1]:.9g} differs from the rod's length {length:.9g} "
                     f"(geometry.length); they must agree to {LENGTH_RTOL:g} relative")
    normal = np.asarray(normal, dtype=float)
    if normal.shape != (3,) or not np.isfinite(normal).all():
        return "normal", "a finite 3-vector"
    if np.linalg.norm(np.cross(normal, chords[0])) <= 1e-9 * np.linalg.norm(normal) * \
            np.linalg.norm(chords[0]):
        return "normal", "parallel to the first segment (it gives d1, perpendicular to the rod)"
    return None


def spin_free(ends, end_rotation, end_turn, end_springs) -> bool:
    """Both ends pinned, no end rotation, turn or spring: turning every section by one
    angle about its director d3 (the rigid rotation about the axis of a straight rod)
    costs no energy, a null mode of a quasi-static rod's tangent (issue 27 item 3; with
    inertia it is a motion, left alone).  EndSupports (rod/boundary_conditions.py) then
    holds the spin about d3 at s = 0 (rotation vectors: theta_3 = 0 there), which adds no
    couple where that mode has zero energy (the reaction is the residual along it, 0);
    where it has energy (anisotropic sections, a natural curvature) it is a torsional
    support at s = 0.  Quaternions: the twist of the start's rotation relative to its
    stress-free one r held (``spin_normal``)."""
    return tuple(ends) == ("pinned", "pinned") and not (end_rotation or end_turn
                                                          or end_springs)


def welded_spin_end(rods, joint_kinds) -> tuple[int, str] | None:
    """Where a system's free spin is held (rod index, end), or None: rods joined by
    rigid joints only (``joint_kinds``; a rod split at its kinks: its corners) move as
    one body, so with exactly two pinned ends among them, every other end free, and no
    end rotation, turn or spring, turning the whole about the line through the pins
    costs no energy, as spin_free's single rod (a welded column pinned at both ends):
    the spin about d3 at the first pinned end is held (EndSupports, rod/
    boundary_conditions.py).  ``rods``: each with ends, end_rotation, end_turn,
    end_springs (rods.Rod)."""
    if len(rods) < 2 or any(kind != "rigid" for kind in joint_kinds):
        return None
    if any(rod.end_rotation or rod.end_turn or rod.end_springs for rod in rods):
        return None
    ends = [(k, end, kind) for k, rod in enumerate(rods)
            for end, kind in zip(("start", "end"), rod.ends)]
    pinned = [(k, end) for k, end, kind in ends if kind == "pinned"]
    if len(pinned) != 2 or any(kind not in ("pinned", "free") for _, _, kind in ends):
        return None
    return pinned[0]


def probed_options(options: dict | None) -> dict:
    """The solver options that fem/solvers.option_problem tries on a throwaway PETSc
    solver: all but LATE_OPTIONS and viewers (none: ``dolfin-rod check`` loads no PETSc)."""
    return {k: v for k, v in (options or {}).items()
            if not (k.startswith(LATE_OPTIONS) or "_view" in k)}
