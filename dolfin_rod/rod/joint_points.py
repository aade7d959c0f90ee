"""Where the joints of a system are, and the checks of them that need no model (numpy
only, no DOLFINx: also ``dolfin-rod check`` of a scene with [[rods]]): the kinds, the
joint's names, a hinge's axis, the rods' nodes at each joint's point (``locate``) and
the starting states meeting there.  The rods are rods.Rod or, from a scene,
placement.PlacedRod; the joints' links and reactions on a model are in joints.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..checks import ENDS
from ..theory.quaternions import CONJ, np_qmul, np_rotation_matrix
from .ring import initial_shape
from .start import RodStarts

KINDS = ("rigid", "ball", "hinge")
AXIS_TOLERANCE = 1e-9       # |axis| - 1 of a hinge's axis


@dataclass
class Joint:
    """A joint of ``kind`` (KINDS) between two rods (names) at ``point``."""

    kind: str
    rods: tuple[str, str]
    point: Sequence[float]
    name: str = ""
    axis: Sequence[float] | None = None     # a hinge's axis (spatial unit vector, t = 0)


def check_joints(joints: list[Joint], rods) -> None:
    """Kinds, rod names and points (a ValueError naming ``joints[k]``)."""
    names = [rod.name for rod in rods]
    for k, joint in enumerate(joints):
        where = f"joints[{k}]"
        if joint.kind not in KINDS:
            raise ValueError(f"{where}.kind must be one of {KINDS}, got {joint.kind!r}")
        if len(joint.rods) != 2 or joint.rods[0] == joint.rods[1] or \
                any(name not in names for name in joint.rods):
            raise ValueError(f"{where}.rods must name two different rods of {names}, got "
                             f"{joint.rods!r}")
        point = np.asarray(joint.point, dtype=float)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"{where}.point must be a finite 3-vector, got {joint.point!r}")
        problem = axis_problem(joint)
        if problem:
            raise ValueError(f"{where}.axis {problem}")
    labels = [joint_label(joint) for joint in joints]
    for k, label in enumerate(labels):
        if labels.index(label) != k:
            raise ValueError(f"joints[{k}].name {label!r} is used twice: give the joints "
                             "of one pair of rods different names")


def axis_problem(joint: Joint) -> str | None:
    """Why a joint's axis is wrong (None if right): a hinge needs a finite unit
    3-vector, the other kinds none."""
    if joint.kind != "hinge":
        return None if joint.axis is None else f"is a hinge's; a {joint.kind} joint has none"
    if joint.axis is None:
        return "is missing: a hinge turns about a given axis"
    axis = np.asarray(joint.axis, dtype=float)
    if axis.shape != (3,) or not np.all(np.isfinite(axis)):
        return f"must be a finite 3-vector, got {joint.axis!r}"
    if abs(np.linalg.norm(axis) - 1.0) > AXIS_TOLERANCE:
        return f"must be a unit vector, got {axis.tolist()} (length {np.linalg.norm(axis):.6g})"
    return None


def joint_label(joint: Joint) -> str:
    """The joint's name in the diagnostics: its name, else "<rod a>-<rod b>"."""
    return joint.name or f"{joint.rods[0]}-{joint.rods[1]}"


def locate(rods, joints: list[Joint]) -> list[tuple[int, int, int, int]]:
    """(rod, node, rod, node) of each joint: the nodes of its two rods (rods.Rod or
    placement.PlacedRod) at its point in the initial configuration; a ValueError naming
    ``joints[k].point`` if it is not a node of both, or ``joints[k]`` if a joined node is
    a supported end."""
    names = [rod.name for rod in rods]
    tol = 1e-9 * max(rod.params.length for rod in rods)
    out = []
    for k, joint in enumerate(joints):
        pair = []
        for name in joint.rods:
            i = names.index(name)
            rod = rods[i]
            s = np.linspace(0.0, rod.params.length, rod.n_cells + 1)
            r = initial_shape(rod, s)[0]
            distance = np.linalg.norm(r - np.asarray(joint.point, float), axis=1)
            node = int(np.argmin(distance))
            if distance[node] > tol:
                raise ValueError(
                    f"joints[{k}].point {list(joint.point)} is not on rod {name!r}: its "
                    f"nearest node is at {r[node].round(12).tolist()} ({distance[node]:.3g} "
                    "away); a joint is at a node of both rods")
            if getattr(rod, "closed", False) and node in (0, rod.n_cells):
                raise ValueError(f"joints[{k}]: the node of rod {name!r} at the point is its "
                                 "weld (a closed rod's s = 0 and s = L): join the ring at "
                                 "another node")
            for end, end_node, kind in zip(ENDS, (0, rod.n_cells), rod.ends):
                held = kind != "free" or end in (rod.end_displacement or {}) or \
                    end in (rod.end_rotation or {})
                if node == end_node and held:
                    raise ValueError(f"joints[{k}]: rod {name!r} is supported at its {end} "
                                     f"(s = {'0' if end == 'start' else 'L'}), where the joint "
                                     "is; a joint joins free ends or interior nodes")
            pair += [i, node]
        out.append(tuple(pair))
    _check_hinge_nodes(joints, out)
    return out


def _check_hinge_nodes(joints: list[Joint], nodes: list[tuple]) -> None:
    """A hinge's nodes in no other joint (its slave rotation is a nonlinear map of a
    free master, fem/multipoint.py): a ValueError naming ``joints[k]``."""
    for k, (joint, (a, i, b, j)) in enumerate(zip(joints, nodes)):
        if joint.kind != "hinge":
            continue
        for other, (c, m, d, n) in enumerate(nodes):
            if other != k and {(a, i), (b, j)} & {(c, m), (d, n)}:
                raise ValueError(f"joints[{k}]: a hinge joins two nodes that no other joint "
                                 f"ties, but joints[{other}] ties one of them too")


START_TOLERANCE = 1e-9     # joined nodes' mismatch in a starting state, relative


def check_joints_at_start(rods, joints: list[Joint], starts: dict) -> None:
    """The starting states (rod/start.RodStarts of ``starts``, {rod name: StartingState})
    keep every joint: its two nodes at one point with the same velocity; rigid: the
    frames' relative rotation as at t = 0 and the same angular velocity; hinge: the
    hinge axis shared and the relative angular velocity along it.  A ValueError naming
    ``start`` and the joint otherwise (no model needed: also ``dolfin-rod check``)."""
    state = RodStarts(starts, rods)
    scale_r = max(rod.params.length for rod in rods)
    for k, (joint, (i, node_a, j, node_b)) in enumerate(zip(joints, locate(rods, joints))):
        (r_a, q_a, v_a, w_a), (r_b, q_b, v_b, w_b) = (
            (part[0] for part in state.rod_state(rods[m], [node * rods[m].params.length /
                                                           rods[m].n_cells]))
            for m, node in ((i, node_a), (j, node_b)))
        R_a, R_b = np_rotation_matrix(q_a), np_rotation_matrix(q_b)
        q_a0, q_b0 = (initial_shape(rods[m], [node * rods[m].params.length / rods[m].n_cells])[1][0]
                      for m, node in ((i, node_a), (j, node_b)))
        relative = np_rotation_matrix(np_qmul(q_a0 * CONJ, q_b0))
        scale_v = max(1.0, np.abs([*v_a, *v_b]).max() + scale_r * np.abs([*w_a, *w_b]).max())
        mismatch = {"position": np.linalg.norm(r_a - r_b) / scale_r,
                    "velocity": np.linalg.norm(v_a - v_b) / scale_v}
        spin = w_b - w_a
        if joint.kind == "rigid":
            mismatch["rotation"] = np.linalg.norm(R_a @ relative - R_b)
            mismatch["angular velocity"] = np.linalg.norm(spin) * scale_r / scale_v
        elif joint.kind == "hinge":
            n = np_rotation_matrix(q_b0).T @ np.asarray(joint.axis, float)
            along = R_b @ n
            mismatch["rotation"] = np.linalg.norm(R_a @ relative @ n - along)
            mismatch["angular velocity"] = np.linalg.norm(
                spin - along * (along @ spin)) * scale_r / scale_v
        for what, value in mismatch.items():
            if value > START_TOLERANCE:
                raise ValueError(f"start: joints[{k}] ({joint_label(joint)}): the starting "
                                 f"states give its two rods a different {what} there "
                                 f"({value:.3g} relative); start the joined rods as the "
                                 "joint holds them")
