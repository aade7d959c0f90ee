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


ROTATIONS = ("auto", "quaternion", "rotation_vector")


def rotation_vector_obstacle(dynamic: bool, variant: str, constraint,
                             rotary_inertia: bool = True, rate_dependent: bool = False,
                             rotation_held: bool = True) -> str | None:
    """Why rotation vectors (rod/rotation_vector.py) do not fit a rod, or None.  They
    need the local variant (the uniform one's real-space natural strains take the
    blocked assembly) and no constraint (its multipliers make a saddle point); a dynamic
    rod needs rotary inertia I11, I22 > 0 (the integrator's start solves the mass
    matrices for the accelerations); a quasi-static rod needs no rate-dependent force
    (``rate_dependent``: Kelvin-Voigt viscosity M, N or drag; its positions and rotations
    are then algebraic unknowns) and an end that holds its rotation (``rotation_held``:
    else a free spin is a null mode of the unpivoted banded LU)."""
    if variant != "local":
        return "the uniform variant (use the local one)"
    if constraint is not None:
        return f"a constrained rod ({constraint})"
    if dynamic and not rotary_inertia:
        return "a dynamic rod without rotary inertia I11, I22 > 0"
    if not dynamic and rate_dependent:
        return "a quasi-static rod with Kelvin-Voigt viscosity (M, N) or drag"
    if not dynamic and not rotation_held:
        return "a quasi-static rod whose rotation no end holds (clamped or end_rotation)"
    return None


def choose_rotations(rotations: str, obstacle: str | None, lie_integrator: bool = True,
                     rotation_jumps: bool = False) -> str:
    """The rod's rotation unknowns (rod/discretisation.py): "auto" takes rotation vectors
    where nothing stands against them (``obstacle``: rotation_vector_obstacle), the
    integrator advances them (``lie_integrator``: generalized-alpha on the rotation
    group for a dynamic rod, any scheme of TimeStepper for a quasi-static one; not PETSc
    TS) and no prescribed end rotation jumps (``rotation_jumps``: a step's nodal
    increment must stay below a quarter turn, RotationVectorChart.check_increment);
    quaternions otherwise.  An explicit choice is checked (ValueError)."""
    if rotations not in ROTATIONS:
        raise ValueError(f"rotations must be one of {ROTATIONS}, got {rotations!r}")
    if rotations == "auto":
        return "rotation_vector" if obstacle is None and lie_integrator \
            and not rotation_jumps else "quaternion"
    if rotations == "rotation_vector" and (obstacle or not lie_integrator):
        why = obstacle or ("PETSc TS or a first-order scheme of a dynamic rod (rotation "
                           "vectors: generalized_alpha[:rho_inf] of TimeStepper)")
        raise ValueError(f"rotations = 'rotation_vector' does not apply to {why}; use "
                         "'quaternion'")
    return rotations
