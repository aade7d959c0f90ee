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
