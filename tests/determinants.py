"""Roots of a boundary-value determinant for the closed-form references of the buckling
and vibration tests: where the column-scaled matrix of a BVP's general solution at its
boundary conditions is singular."""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar


def smallest_singular_value(D: np.ndarray) -> float:
    """Smallest singular value of D with its columns scaled to unit norm."""
    return np.linalg.svd(D / np.linalg.norm(D, axis=0), compute_uv=False)[-1]


def first_root(f, grid: np.ndarray) -> float:
    """The first local minimum of f (a smallest singular value) on ``grid``, refined by
    minimize_scalar; asserted to be a root (f < 1e-6), not a near miss."""
    values = [f(x) for x in grid]
    k = next(k for k in range(1, len(grid) - 1)
             if values[k] < values[k - 1] and values[k] < values[k + 1])
    found = minimize_scalar(f, bounds=(grid[k - 1], grid[k + 1]), method="bounded",
                            options={"xatol": 1e-12})
    assert found.fun < 1e-6                            # a root, not a near miss
    return found.x
