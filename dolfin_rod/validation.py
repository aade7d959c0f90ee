"""Input checks shared by the modules: errors name the parameter and the rule."""

from __future__ import annotations

import math
import numbers


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
