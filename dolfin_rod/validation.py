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


def choose_rotations(rotations: str, dynamic: bool, variant: str, constraint,
                     lie_integrator: bool = True, rotary_inertia: bool = True) -> str:
    """The rod's rotation unknowns (rod/discretisation.py): "auto" takes rotation vectors
    for a dynamic rod with rotary inertia (``rotary_inertia``: I11, I22 > 0; the
    integrator's start solves the mass matrices for the accelerations), the local
    variant and no constraint, advanced by the rotation-group integrator
    (``lie_integrator``: not a first-order scheme or PETSc TS), quaternions otherwise; an
    explicit choice is checked (ValueError)."""
    if rotations not in ROTATIONS:
        raise ValueError(f"rotations must be one of {ROTATIONS}, got {rotations!r}")
    fits = dynamic and rotary_inertia and variant == "local" and constraint is None
    if rotations == "auto":
        return "rotation_vector" if fits and lie_integrator else "quaternion"
    if rotations == "rotation_vector" and not (fits and lie_integrator):
        raise ValueError("rotations = 'rotation_vector' needs a dynamic rod (rho_A > 0, and "
                         "rotary inertia I11, I22 > 0) with the local variant and no "
                         "constraint, advanced by generalized_alpha[:rho_inf] (TimeStepper); "
                         "use 'quaternion'")
    return rotations
