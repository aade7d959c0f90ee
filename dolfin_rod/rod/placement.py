"""Where a rod is at t = 0, in numpy only (no DOLFINx: also ``dolfin-rod check``): its
stress-free shape (the helix of its reference strains, or the curve
``reference_shape``: rod/start.py) turned by its orientation and moved to its position.

The functions read a rod's ``params`` (length, reference strains and shape), ``n_cells``,
``position`` and ``orientation``: a rods.Rod, or a ``PlacedRod`` (the same attributes,
built from a scene without RodParameters, whose materials load DOLFINx)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..theory.quaternions import np_qmul, np_quaternion_from_rotation_vector, np_rotation_matrix


@dataclass(frozen=True)
class Geometry:
    """The parts of a rod's RodParameters (material.py) that give its stress-free shape."""

    length: float
    reference_curvature: Sequence[float] = (0.0, 0.0, 0.0)
    reference_stretch: Sequence[float] = (0.0, 0.0, 1.0)
    reference_shape: Any = None          # a curve of rod/start.py


@dataclass(frozen=True)
class PlacedRod:
    """The attributes of a rods.Rod that place it and hold its ends (joint_checks.py)."""

    name: str
    params: Geometry
    n_cells: int
    ends: tuple[str, str]
    end_displacement: dict | None = None
    end_rotation: dict | None = None
    position: Sequence[float] = (0.0, 0.0, 0.0)
    orientation: Sequence[float] = (0.0, 0.0, 0.0)
    closed: bool = False                 # a ring (rod/ring.py): it starts as its ring
    excess_link: float = 0.0


def helix(s, u0, v0):
    """Stress-free configuration of constant strains: q(s) = exp(s u0/2), r = int R v0."""
    u0, v0 = np.asarray(u0, float), np.asarray(v0, float)
    q = np_quaternion_from_rotation_vector(np.outer(s, u0))
    if not u0.any():    # straight: what the loop gives, (s I) v0 with no -0.0, at once
        return np.outer(s, v0) + 0.0, q
    a = np.linalg.norm(u0)
    U = np.array([[0, -u0[2], u0[1]], [u0[2], 0, -u0[0]], [-u0[1], u0[0], 0]])
    r = np.zeros((len(s), 3))
    for i, si in enumerate(s):
        if a * si < 1e-4:  # series of (1 - cos)/a^2 and (a s - sin)/a^3 (no 0/0)
            c1 = si**2 / 2 - a**2 * si**4 / 24
            c2 = si**3 / 6 - a**2 * si**5 / 120
        else:
            c1 = (1 - np.cos(a * si)) / a**2
            c2 = (a * si - np.sin(a * si)) / a**3
        r[i] = (si * np.eye(3) + c1 * U + c2 * U @ U) @ v0
    return r, q


def shape(params, s, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) of a rod's stress-free shape at its nodes' arc lengths s, from the origin
    with R(0) = I: the curve ``params.reference_shape`` (rod/start.py), else the helix of
    the reference strains."""
    if params.reference_shape is not None:
        return params.reference_shape.frames(s, params.length, n_cells)
    return helix(s, params.reference_curvature, params.reference_stretch)


def placed_shape(rod, s) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) of one rod (rods.Rod or PlacedRod) at its own arc lengths s: its stress-free
    shape, turned by its orientation, moved to its position."""
    return place(rod, *shape(rod.params, s, rod.n_cells))


def place(rod, r, q) -> tuple[np.ndarray, np.ndarray]:
    """Positions r and rotations q in a rod's own frame turned by its orientation and
    moved to its position (rods.Rod or PlacedRod)."""
    turn = np_quaternion_from_rotation_vector(np.asarray(rod.orientation, float))
    return (np.asarray(rod.position, float) + r @ np_rotation_matrix(turn).T,
            np_qmul(turn, q))
