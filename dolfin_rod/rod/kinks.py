"""A stress-free polyline with kinks, split into rigidly joined pieces (issue 25).

A rod whose stress-free shape (RodParameters.reference_shape) is a Polyline turning at
points that sit at mesh nodes has rigid corners there.  One rod of P1 rotations cannot
hold a corner: it spreads the corner's turn over the node's two cells (the node's d3
bisects it), a frame with a rigid corner only to first order in h.  So a RodModel splits
such a rod at those nodes into pieces, each straight (or a polyline bending between
nodes), joined by rigid joints (joints.py: two nodes at one point, their frames keeping
the corner's angle exactly, no penalty): the frame of rods and joints, at the smooth
rod's order (tests/test_reference_shape.py).

Piece k covers the rest arc lengths [s_k, s_k+1] of the rod (``offsets``: its loads and
coefficients are the rod's at s_k + its own arc length, layout.Pieces.local_s), starts
at the polyline's point there with the frame of the segment after it (d3 along the
segment, d1 carried along the segments by parallel transport from ``normal``, as the
polyline's own frames), placed as the rod is.  The first piece takes the rod's name, its
support at s = 0, the start's loads and motions; the last one the end's (s = L); the
ends between pieces are free (the joints hold them).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..theory.quaternions import (CONJ, np_qmul, np_quaternion_from_matrix,
                                  np_quaternion_from_rotation_vector, np_rotation_matrix,
                                  np_rotation_vector)
from .joint_points import Joint
from .rods import Rod
from .start import Polyline, StartingState, parallel_transport

KINK = 1e-9          # rad: a polyline point turning by more is a corner
AT_NODE = 1e-9       # a point within AT_NODE h of a node is at the node


@dataclass(frozen=True)
class Split:
    """The pieces of a rod (rods.Rod), the rigid joints between them, and the rest arc
    length of each piece's start on the rod."""

    rods: list
    joints: list
    offsets: tuple


def corner_nodes(params, n_cells: int) -> list[int]:
    """The interior nodes (indices 1..n_cells-1) at which the stress-free polyline
    turns (by more than KINK); none for any other shape."""
    shape = params.reference_shape
    if not isinstance(shape, Polyline):
        return []
    points, arc = np.asarray(shape.points, float), shape.arc_lengths()
    chords = _unit(np.diff(points, axis=0))
    turns = np.einsum("ij,ij->i", chords[:-1], chords[1:]) < np.cos(KINK)
    position = arc[1:-1] * n_cells / float(params.length)
    nodes = np.rint(position).astype(int)
    at_node = turns & (np.abs(position - nodes) < AT_NODE) & (nodes > 0) & (nodes < n_cells)
    return sorted(set(nodes[at_node].tolist()))


def split_at_kinks(rod: Rod) -> Split:
    """The rod as pieces joined rigidly at its corner nodes (see module); the rod itself,
    no joints, if it has none."""
    corners = corner_nodes(rod.params, rod.n_cells)
    if not corners:
        return Split([rod], [], (0.0,))
    L, n = float(rod.params.length), rod.n_cells
    h = L / n
    bounds = [0, *corners, n]
    shape = rod.params.reference_shape
    points, arc = np.asarray(shape.points, float), shape.arc_lengths()
    frames = _segment_frames(points, np.asarray(shape.normal, float))
    turn = np_quaternion_from_rotation_vector(np.asarray(rod.orientation, float))
    Q, p = np_rotation_matrix(turn), np.asarray(rod.position, float)
    pieces, joints = [], []
    for k, (i, j) in enumerate(zip(bounds[:-1], bounds[1:])):
        s0, s1 = i * h, j * h
        segment = min(int(np.searchsorted(arc, s0 + 0.5 * h)) - 1, len(frames) - 1)
        start = np.array([np.interp(s0, arc, points[:, c]) for c in range(3)])
        R = frames[segment]
        inner = (arc > s0 + AT_NODE * h) & (arc < s1 - AT_NODE * h)
        local = None
        if np.any(inner):           # corners between nodes: a polyline of its own
            end = np.array([np.interp(s1, arc, points[:, c]) for c in range(3)])
            local = Polyline(tuple(map(tuple, (np.vstack([start, points[inner], end])
                                               - start) @ R)),
                             tuple([0.0, *(arc[inner] - s0), s1 - s0]))
        pieces.append(replace(
            rod, params=replace(rod.params, length=s1 - s0, reference_shape=local),
            n_cells=j - i, name=rod.name if k == 0 else f"{rod.name}-{k}",
            position=tuple(p + Q @ start),
            orientation=tuple(np_rotation_vector(np_qmul(turn, np_quaternion_from_matrix(R)))),
            point_loads=[replace(load, s=load.s - s0) for load in rod.point_loads
                         if s0 <= load.s < s1 or (j == n and load.s == s1)],
            **_ends(rod, first=k == 0, last=j == n)))
        if k > 0:
            joints.append(Joint("rigid", (pieces[k - 1].name, pieces[k].name),
                                tuple(p + Q @ start), name=f"{rod.name}-corner{k}"))
    return Split(pieces, joints, tuple(i * h for i in bounds[:-1]))


def piece_starts(start: StartingState, split: Split) -> dict:
    """{piece name: StartingState}: the rod's starting state (its stress-free shape
    placed at ``position`` with ``orientation``, velocities) as its pieces' (rod/start.
    RodStarts: each in its piece's placed frame p_k, R_k): the rod's r = p + Q r_rod is
    p_k + R_k (p'' + Q'' r_piece) with Q'' = R_k^T Q R_k, p'' = R_k^T (p + Q p_k - p_k);
    velocity fields of the rod's s taken at the piece's s + offset.  A starting curve
    (``shape``) is a ValueError naming ``start.shape`` (not split yet)."""
    if start.shape is not None:
        raise ValueError("start.shape: a rod whose stress-free polyline is split at its "
                         "kinks (rod/kinks.py) starts in its stress-free shape (placed, "
                         "with velocities), not on a curve yet")
    q = np_quaternion_from_rotation_vector(np.asarray(start.orientation, float))
    Q, p = np_rotation_matrix(q), np.asarray(start.position, float)
    starts = {}
    for piece, offset in zip(split.rods, split.offsets):
        q_k = np_quaternion_from_rotation_vector(np.asarray(piece.orientation, float))
        R_k, p_k = np_rotation_matrix(q_k), np.asarray(piece.position, float)
        starts[piece.name] = replace(
            start, position=tuple(R_k.T @ (p + Q @ p_k - p_k)),
            orientation=tuple(np_rotation_vector(np_qmul(np_qmul(q_k * CONJ, q), q_k))),
            velocity=_at_offset(start.velocity, offset),
            angular_velocity=_at_offset(start.angular_velocity, offset))
    return starts


def _at_offset(field, offset: float):
    """A velocity field of the rod's s as one of a piece's own s (a constant as is)."""
    return (lambda s: field(np.asarray(s, float) + offset)) if callable(field) else field


def _ends(rod: Rod, first: bool, last: bool) -> dict:
    """A piece's supports, end loads and end motions: the rod's at the ends it has."""
    keep = {"start": first, "end": last}
    own = {name: {end: v for end, v in (getattr(rod, name) or {}).items() if keep[end]}
           or None for name in ("end_displacement", "end_rotation", "end_slide",
                                "end_springs", "end_turn")}
    return dict(own, start=rod.start if first else "free", end=rod.end if last else "free",
                end_loads=[load for load in rod.end_loads if keep[load.end]])


def _segment_frames(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The rotation (d1, d2, d3) of each segment: d3 along it, d1 from ``normal`` carried
    from segment to segment by parallel transport (start.Polyline's own rule)."""
    chords = _unit(np.diff(points, axis=0))
    d1 = parallel_transport(chords, normal)
    return np.stack([d1, np.cross(chords, d1), chords], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1)[:, None]
