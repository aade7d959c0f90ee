"""A stress-free polyline with kinks, split into rigidly joined pieces (issue 25).

One rod of P1 rotations cannot hold a corner: it spreads the corner's turn over the
cells around it (a node's d3 bisects a corner at the node; a corner inside a cell turns
that cell's chord), a frame with a rigid corner only to first order in h.  So a rod
whose stress-free shape (RodParameters.reference_shape) is a Polyline turning at some
of its points (by more than KINK) is split at every such corner, wherever it falls, into
straight pieces joined by rigid joints (joints.py: two nodes at one point, their frames
keeping the corner's angle exactly, no penalty): the frame of rods and joints, at the
smooth rod's order (tests/test_reference_shape.py).

Piece k covers the rest arc lengths [s_k, s_k+1] between two corners (``offsets``: its
loads and coefficients are the rod's at s_k + its own arc length, layout.Pieces.
local_s) with ``piece_cells`` cells: the rod's n_cells shared in proportion to the
pieces' lengths (largest remainders, at least 1 each: the total is n_cells unless a
piece needed its 1; a corner at a node keeps the rod's own cells).  A piece starts at
its corner point with the frame of its segment (d3 along it, d1 carried along the
segments by parallel transport from ``normal``, as the polyline's own frames), placed
as the rod is, and is stretched by its chord over its rest length (1 unless the
polyline has a ``rest_arc_length``).  The first piece takes the rod's name, its support
at s = 0, the start's loads and motions; the last one the end's (s = L); the ends
between pieces are free (the joints hold them), and each corner's joint is named
"<rod>-corner<k>" (its reactions: joints.JointReactions).  Numpy only (``dolfin-rod
check`` splits a scene's rods too: ``split_placed``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..theory.quaternions import (CONJ, np_qmul, np_quaternion_from_matrix,
                                  np_quaternion_from_rotation_vector, np_rotation_matrix,
                                  np_rotation_vector)
from .joint_points import Joint, check_joints_at_start, joint_label
from .placement import Geometry, PlacedRod, placed_shape
from .start import Polyline, StartingState, parallel_transport

KINK = 1e-9          # rad: a polyline point turning by more is a corner


@dataclass(frozen=True)
class Split:
    """The pieces of a rod (rods.Rod or placement.PlacedRod), the rigid joints between
    them, the rest arc length of each piece's start on the rod, and where the pieces
    are (``parts``: Piece; none for a rod not split)."""

    rods: list
    joints: list
    offsets: tuple
    parts: tuple = ()


@dataclass(frozen=True)
class Piece:
    """Where a piece of a split rod is: rest arc lengths [s0, s1] on the rod, cells,
    placed start and orientation (a rotation vector), stretch of its straight shape;
    its start ``point`` and ``frame`` (rotation matrix) in the rod's own frame."""

    s0: float
    s1: float
    n_cells: int
    position: tuple
    orientation: tuple
    stretch: float
    point: tuple
    frame: tuple


def corner_indices(shape) -> np.ndarray:
    """The indices of a stress-free Polyline's interior points where it turns by more
    than KINK (none for any other shape)."""
    if not isinstance(shape, Polyline):
        return np.zeros(0, dtype=int)
    chords = _unit(np.diff(np.asarray(shape.points, float), axis=0))
    turns = np.einsum("ij,ij->i", chords[:-1], chords[1:]) < np.cos(KINK)
    return np.flatnonzero(turns) + 1


def piece_cells(lengths, n_cells: int) -> list[int]:
    """n_cells shared among pieces in proportion to their lengths: the floors of the
    shares, the cells left to the largest remainders (ties: the earlier piece), at
    least 1 each.  Shares that are whole numbers (corners at the rod's nodes) stay
    exactly those (a round-off below them leaves a remainder near 1, which gets the
    cell back)."""
    lengths = np.asarray(lengths, float)
    share = n_cells * lengths / lengths.sum()
    cells = np.floor(share).astype(int)
    left = n_cells - int(cells.sum())
    cells[np.argsort(-(share - cells), kind="stable")[:max(left, 0)]] += 1
    return np.maximum(cells, 1).tolist()


def pieces(rod) -> list[Piece]:
    """The pieces of a rod (rods.Rod or placement.PlacedRod) between the corners of its
    stress-free polyline (see module); [] if it has none."""
    shape = rod.params.reference_shape
    corners = corner_indices(shape)
    if not len(corners):
        return []
    points, arc = np.asarray(shape.points, float), shape.arc_lengths()
    frames = _segment_frames(points, np.asarray(shape.normal, float))
    bounds = [0, *corners.tolist(), len(points) - 1]
    cells = piece_cells(np.diff(arc[bounds]), rod.n_cells)
    turn = np_quaternion_from_rotation_vector(np.asarray(rod.orientation, float))
    Q, p = np_rotation_matrix(turn), np.asarray(rod.position, float)
    out = []
    for i, j, n in zip(bounds[:-1], bounds[1:], cells):
        chord = np.linalg.norm(points[j] - points[i])
        out.append(Piece(
            float(arc[i]), float(arc[j]), n, tuple(p + Q @ points[i]),
            tuple(np_rotation_vector(np_qmul(turn, np_quaternion_from_matrix(frames[i])))),
            1.0 if shape.rest_arc_length is None else chord / (arc[j] - arc[i]),
            tuple(points[i]), tuple(map(tuple, frames[i]))))
    return out


def describe(label: str, shape, length: float, n_cells: int) -> str | None:
    """What ``dolfin-rod check`` says of a rod (``label``: "the rod", "rod 'a'") whose
    stress-free ``shape`` is split at its corners (None: not split)."""
    parts = pieces(PlacedRod("", Geometry(length, reference_shape=shape), n_cells,
                             ("free", "free")))
    if not parts:
        return None
    cells = [part.n_cells for part in parts]
    at = ", ".join(f"{part.s0:.6g}" for part in parts[1:])
    return (f"{label} is split at its corners (s = {at}) into {len(parts)} straight pieces "
            f"joined rigidly, of {', '.join(map(str, cells))} cells (in proportion to "
            f"their lengths: {sum(cells)} cells, geometry.n_cells = {n_cells})")


def split_at_kinks(rod) -> Split:
    """The rod (rods.Rod) as pieces joined rigidly at its corners (see module); the rod
    itself, no joints, if it has none."""
    parts = pieces(rod)
    if not parts:
        return Split([rod], [], (0.0,))
    out = []
    for k, part in enumerate(parts):
        first, last = k == 0, k == len(parts) - 1
        out.append(replace(
            _piece(rod, k, part),
            point_loads=[replace(load, s=load.s - part.s0) for load in rod.point_loads
                         if part.s0 <= load.s < part.s1 or (last and load.s == part.s1)],
            **_held(rod, first, last, ("end_displacement", "end_rotation", "end_slide",
                                       "end_springs", "end_turn")),
            start=rod.start if first else "free", end=rod.end if last else "free",
            end_loads=[load for load in rod.end_loads
                       if (load.end == "start" and first) or (load.end == "end" and last)]))
    return _joined(rod.name, out, parts)


def split_placed(rod) -> Split:
    """split_at_kinks of a placement.PlacedRod (``dolfin-rod check``: numpy only)."""
    parts = pieces(rod)
    if not parts:
        return Split([rod], [], (0.0,))
    out = [replace(_piece(rod, k, part),
                   ends=(rod.ends[0] if k == 0 else "free",
                         rod.ends[1] if k == len(parts) - 1 else "free"),
                   **_held(rod, k == 0, k == len(parts) - 1, ("end_displacement",
                                                              "end_rotation")))
           for k, part in enumerate(parts)]
    return _joined(rod.name, out, parts)


def _piece(rod, k: int, part: Piece):
    """Piece k of a rod: straight, of its length, cells, place and name."""
    stretch = (0.0, 0.0, part.stretch) if part.stretch != 1.0 else rod.params.reference_stretch
    return replace(rod, params=replace(rod.params, length=part.s1 - part.s0,
                                       reference_shape=None, reference_stretch=stretch),
                   n_cells=part.n_cells, name=rod.name if k == 0 else f"{rod.name}-{k}",
                   position=part.position, orientation=part.orientation)


def _joined(name: str, rods: list, parts: list[Piece]) -> Split:
    """The pieces with the rigid joints at their corners."""
    joints = [Joint("rigid", (a.name, b.name), part.position, name=f"{name}-corner{k + 1}")
              for k, (a, b, part) in enumerate(zip(rods[:-1], rods[1:], parts[1:]))]
    return Split(rods, joints, tuple(part.s0 for part in parts), tuple(parts))


def attach(joints: list, splits: list[Split]) -> list:
    """A system's joints on the pieces of its split rods (``splits``, one a rod): a joint
    naming a split rod is on the piece with a node nearest its point (at a corner: the
    piece before it), its label kept (joint_points.joint_label); then every corner's
    rigid joint."""
    split_of = {split.rods[0].name: split for split in splits if len(split.rods) > 1}
    out = []
    for joint in joints:
        names = tuple(_piece_at(split_of[name], joint.point) if name in split_of else name
                      for name in joint.rods)
        out.append(joint if names == tuple(joint.rods) else
                   replace(joint, rods=names, name=joint_label(joint)))
    return out + [corner for split in splits for corner in split.joints]


def _piece_at(split: Split, point) -> str:
    """The name of the piece of ``split`` with a node nearest ``point``."""
    distance = [np.linalg.norm(placed_shape(piece, np.linspace(
        0.0, piece.params.length, piece.n_cells + 1))[0] - np.asarray(point, float),
        axis=1).min() for piece in split.rods]
    return split.rods[int(np.argmin(distance))].name


def system_starts(starts: dict, splits: list[Split]) -> dict:
    """A system's starting states {rod name: StartingState} as its pieces' (a split
    rod's by ``piece_starts``, the others' as given)."""
    out = {}
    for name, start in starts.items():
        split = next((split for split in splits if split.rods[0].name == name), None)
        out.update(piece_starts(start, split) if split and len(split.rods) > 1
                   else {name: start})
    return out


def piece_starts(start: StartingState, split: Split) -> dict:
    """{piece name: StartingState}: the rod's starting state as its pieces' (rod/start.
    RodStarts: each in its piece's placed frame), with p_k, R_k the piece's start and
    frame in the rod's own frame and r = p + Q r_rod the rod's start (then placed as the
    rod).  Its stress-free shape (``shape`` None): r_rod = p_k + R_k r_piece, so the
    piece starts at p'' = R_k^T (p + Q p_k - p_k) turned by Q'' = R_k^T Q R_k.  A starting
    polyline c(s) (``shape``, in the rod's own frame): piece k starts on its part over
    [s_k, s_k+1] (``_piece_curve``), at p'' = R_k^T (p + Q c(s_k) - p_k) turned by
    Q'' = R_k^T Q.  Velocity fields of the rod's s are taken at the piece's s + offset."""
    if start.shape is not None and not isinstance(start.shape, Polyline):
        raise ValueError(f"start.shape: a rod split at its corners (rod/kinks.py: rigid, "
                         f"they keep their angle) starts on a polyline with the same "
                         f"corners, not on a smooth {type(start.shape).__name__.lower()}")
    q = np_quaternion_from_rotation_vector(np.asarray(start.orientation, float))
    Q, p = np_rotation_matrix(q), np.asarray(start.position, float)
    normals = _piece_normals(start.shape, split.parts) if start.shape else None
    starts = {}
    for k, (piece, offset, part) in enumerate(zip(split.rods, split.offsets, split.parts)):
        R_k, p_k = np.asarray(part.frame, float), np.asarray(part.point, float)
        if start.shape is None:
            q_k = np_quaternion_from_matrix(R_k)
            moved = dict(position=tuple(R_k.T @ (p + Q @ p_k - p_k)), orientation=tuple(
                np_rotation_vector(np_qmul(np_qmul(q_k * CONJ, q), q_k))))
        else:
            curve, c0 = _piece_curve(start.shape, part, normals[k])
            moved = dict(shape=curve, position=tuple(R_k.T @ (p + Q @ c0 - p_k)),
                         orientation=tuple(np_rotation_vector(np_quaternion_from_matrix(
                             R_k.T @ Q))))
        starts[piece.name] = replace(
            start, **moved, velocity=_at_offset(start.velocity, offset),
            angular_velocity=_at_offset(start.angular_velocity, offset))
    if start.shape is not None:
        try:
            check_joints_at_start(split.rods, split.joints, starts)
        except ValueError as err:
            raise ValueError(f"start.shape: the starting polyline does not keep the rod's "
                             f"rigid corners as they are in its stress-free shape, at the "
                             f"same rest arc lengths with the same angles ({err})") from None
    return starts


def _piece_curve(shape: Polyline, part: Piece, normal) -> tuple[Polyline, np.ndarray]:
    """The part of a starting polyline over a piece's rest arc lengths [s0, s1], from
    its point c(s0) (returned too), d1 from ``normal`` there."""
    points, arc = np.asarray(shape.points, float), shape.arc_lengths()
    tol = 1e-9 * arc[-1]
    inner = (arc > part.s0 + tol) & (arc < part.s1 - tol)
    ends = [np.array([np.interp(s, arc, points[:, c]) for c in range(3)])
            for s in (part.s0, part.s1)]
    line = np.vstack([ends[0], points[inner], ends[1]]) - ends[0]
    rest = np.concatenate([[0.0], arc[inner] - part.s0, [part.s1 - part.s0]])
    return Polyline(tuple(map(tuple, line)), tuple(rest), tuple(normal)), ends[0]


def _piece_normals(shape: Polyline, parts) -> list:
    """d1 at each piece's start on a starting polyline: the polyline's own rule (start.
    Polyline: d3 the mean tangent of a node's two cells, d1 from ``normal`` carried from
    node to node by parallel transport) over the pieces' nodes in turn, carried across
    each corner from the tangent before it to the one after it."""
    points, arc = np.asarray(shape.points, float), shape.arc_lengths()
    normals, carried = [], None
    for part in parts:
        grid = np.linspace(part.s0, part.s1, part.n_cells + 1)
        nodes = np.stack([np.interp(grid, arc, points[:, c]) for c in range(3)], axis=1)
        chords = _unit(np.diff(nodes, axis=0))
        tangents = _unit(np.concatenate((chords[:1], chords[:-1] + chords[1:], chords[-1:])))
        d = (np.asarray(shape.normal, float) if carried is None else
             parallel_transport(np.array([carried[1], tangents[0]]), carried[0])[1])
        d1 = parallel_transport(tangents, d)
        normals.append(d1[0])
        carried = (d1[-1], tangents[-1])
    return normals


def _at_offset(field, offset: float):
    """A velocity field of the rod's s as one of a piece's own s (a constant as is)."""
    return (lambda s: field(np.asarray(s, float) + offset)) if callable(field) else field


def _held(rod, first: bool, last: bool, names: tuple) -> dict:
    """A piece's end motions and supports given per end ({end: value}): the rod's at the
    ends it has."""
    keep = {"start": first, "end": last}
    return {name: {end: v for end, v in (getattr(rod, name) or {}).items() if keep[end]}
            or None for name in names}


def _segment_frames(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The rotation (d1, d2, d3) of each segment: d3 along it, d1 from ``normal`` carried
    from segment to segment by parallel transport (start.Polyline's own rule)."""
    chords = _unit(np.diff(points, axis=0))
    d1 = parallel_transport(chords, normal)
    return np.stack([d1, np.cross(chords, d1), chords], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1)[:, None]
