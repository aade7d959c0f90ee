"""Input checks shared by the modules: errors name the parameter and the rule."""

from __future__ import annotations

import math
import numbers

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


# The cells of a rod or a torsion model unless given: the one default of RodModel, Rod,
# TorsionModel and the scene key geometry.n_cells.
N_CELLS = 32

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
    """Why ``axis`` cannot be a slide axis (None if it can): not a finite unit 3-vector
    along a coordinate axis (Dirichlet conditions on the other two components)."""
    a = np.asarray(axis, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        return f"must be a finite 3-vector, got {axis!r}"
    if abs(np.linalg.norm(a) - 1.0) > 1e-12:
        return f"must be a unit vector, got {a.tolist()} (length {np.linalg.norm(a):.6g})"
    if np.count_nonzero(a) != 1:
        return (f"must be a coordinate axis (+-e_1, +-e_2 or +-e_3), got {a.tolist()}: "
                "an end sliding along a direction off the axes is not supported")
    return None
