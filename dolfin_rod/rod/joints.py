"""Joints between the rods of a system (system.RodSystem): exact, no penalty.

    Joint("rigid", ("a", "b"), point)   position and rotation shared: the rods' frames
                                        keep the angle they have at the point at t = 0
    Joint("ball", ("a", "b"), point)    position shared, rotations independent
    Joint("hinge", ("a", "b"), point, axis=(0, 1, 0))
                                        position shared, rotations equal up to a turn
                                        about the hinge axis (spatial, at t = 0), which
                                        turns with both rods

``point`` is where the joint is in the initial (stress-free, placed) configuration; it
must be a node of both rods (an end or an interior node).  The second rod's node is
tied to the first's (fem/multipoint.py): x_b = x_a + (s_a - s_b) e_3 (the same
centre-line point: r = s e_3 + x) and, rigid, theta_b = R_rel^T theta_a with R_rel =
R(q_a)^T R(q_b) at t = 0, which keeps q_b = q_a R_rel exactly (rotation_vector.py:
conj(Q) c(theta) Q = c(R(Q)^T theta)).  A hinge keeps q_b = q_a R_rel H(phi), H a turn
by phi about the axis n (in b's material frame: R(q_b)^T axis at t = 0); per step,
with Q = conj(q_n,a) q_n,b = R_rel H(phi_n) of the stored rotations, c(theta_b) =
c(R(Q)^T theta_a) H(phi - phi_n), not linear in the increments: the slave's rotation is
a nonlinear map (fem/multipoint.NodeMap, ``Hinge``) of theta_a and the hinge's own
unknown psi = 2 tan((phi - phi_n)/2).  The Newton unknowns are the free dofs only, so
the system keeps the structure of its rods (no multiplier, no saddle point).  A joined
node carries no support (the rods' joined ends are "free"); several joints at one point
(a tripod) tie every rod to the first.

Reactions: the force and couple the joint exerts on the second rod,
``joint_<name>_force_{xyz}``, ``joint_<name>_couple_{xyz}`` (spatial components): the
second rod's residual at its joined node (as the reactions at a support).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import dolfinx.fem as fem
import numpy as np

from ..fem.multipoint import NodeLink, NodeMap
from ..fem.fe_model import ENDS, NodeValues, near_nodes, nodal_residual
from ..theory.rotations import np_qmul, np_rotation_matrix
from .boundary_conditions import spatial_rotations
from .initial_state import placed_shape, stress_free
from .start import RodStarts

KINDS = ("rigid", "ball", "hinge")
_CONJ = np.array([1.0, -1, -1, -1])
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


def joint_nodes(model, joints: list[Joint]) -> list[tuple[float, float]]:
    """(s of the first rod's node, s of the second rod's node) on the system's mesh at
    each joint (``locate``)."""
    layout = model.layout
    starts, h = layout.starts, [L / n for L, n in zip(layout.lengths, layout.n_cells)]
    return [(starts[k_a] + i_a * h[k_a], starts[k_b] + i_b * h[k_b])
            for k_a, i_a, k_b, i_b in locate(model.rods, joints)]


def locate(rods, joints: list[Joint]) -> list[tuple[int, int, int, int]]:
    """(rod, node, rod, node) of each joint: the nodes of its two rods (rods.Rod) at its
    point in the initial configuration; a ValueError naming ``joints[k].point`` if it
    is not a node of both, or ``joints[k]`` if a joined node is a supported end."""
    names = [rod.name for rod in rods]
    tol = 1e-9 * max(rod.params.length for rod in rods)
    out = []
    for k, joint in enumerate(joints):
        pair = []
        for name in joint.rods:
            i = names.index(name)
            rod = rods[i]
            s = np.linspace(0.0, rod.params.length, rod.n_cells + 1)
            r = placed_shape(rod, s)[0]
            distance = np.linalg.norm(r - np.asarray(joint.point, float), axis=1)
            node = int(np.argmin(distance))
            if distance[node] > tol:
                raise ValueError(
                    f"joints[{k}].point {list(joint.point)} is not on rod {name!r}: its "
                    f"nearest node is at {r[node].round(12).tolist()} ({distance[node]:.3g} "
                    "away); a joint is at a node of both rods")
            for end, end_node, kind in zip(ENDS, (0, rod.n_cells), rod.ends):
                held = kind != "free" or end in (rod.end_displacement or {}) or \
                    end in (rod.end_rotation or {})
                if node == end_node and held:
                    raise ValueError(f"joints[{k}]: rod {name!r} is supported at its {end} "
                                     "end, where the joint is; a joint joins free ends or "
                                     "interior nodes")
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


def node_links(model, joints: list[Joint], nodes) -> list[NodeLink | NodeMap]:
    """The links of the joints (fem/multipoint.py): displacement of the second rod's
    node = the first's; rigid: rotation increment theta_b = R_rel^T theta_a; hinge: the
    NodeMap of ``Hinge``."""
    blocks = model.names
    rotation = blocks.index(model.unknowns.rotation)
    links = []
    for joint, (s_a, s_b) in zip(joints, nodes):
        links.append(NodeLink(blocks.index("displacement"), s_a, s_b,
                              tuple(map(tuple, np.eye(3)))))
        q_a, q_b = stress_free(model, np.array([s_a, s_b]))[1]
        if joint.kind == "rigid":
            relative = np_rotation_matrix(np_qmul(q_a * _CONJ, q_b))
            links.append(NodeLink(rotation, s_a, s_b, tuple(map(tuple, relative.T))))
        elif joint.kind == "hinge":
            axis = np_rotation_matrix(q_b).T @ np.asarray(joint.axis, float)
            law = Hinge(axis, model.unknowns.f[model.unknowns.rotation],
                        stored_rotations(model, (s_a, s_b)))
            links.append(NodeMap(rotation, s_a, s_b, law))
    return links


def stored_rotations(model, nodes: tuple[float, float]):
    """() -> the stored nodal quaternions q_n at the two nodes (collective)."""
    q_n = model.unknowns.chart.q_n
    at_nodes = NodeValues(q_n.function_space, list(nodes))
    return lambda: at_nodes(q_n.x.array)


def _skew(n: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])


class Hinge:
    """The slave rotation increment of a hinge (fem/multipoint.NodeMap's law): with
    alpha = R(Q)^T theta_a (Q = conj(q_n,a) q_n,b, refreshed at each solve's start) and
    the hinge's own unknown psi, c(theta_b) = c(alpha) c(psi n), i.e. (Gibbs vectors
    theta/2 compose as (g1 + g2 + g1 x g2)/(1 - g1.g2))

        theta_b = (alpha + psi n + psi/2 alpha x n) / (1 - psi alpha.n/4),

    exact for the rotation increments (``configuration``); its tangent at 0,
    alpha + psi n, for their rates and accelerations (the start's accelerations: exact
    when the hinge does not turn at t = 0)."""

    size = 1

    def __init__(self, axis: np.ndarray, configuration=None, stored_rotations=None):
        self.axis = np.asarray(axis, float)     # n, in the second rod's material frame
        self.configuration = configuration      # the rotation increments' Function
        self.stored_rotations = stored_rotations  # () -> (q_n,a, q_n,b), collective
        self.Q = np.eye(3)

    def refresh(self) -> None:
        """Q from the stored rotations of the two nodes."""
        q_a, q_b = self.stored_rotations()
        if q_a @ q_a > 0 and q_b @ q_b > 0:          # (zero before set_initial_state)
            self.Q = np_rotation_matrix(np_qmul(q_a * _CONJ, q_b))

    def value(self, theta_a, own, exact: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(theta_b, d theta_b / d(theta_a, psi)) at theta_a, own = [psi]."""
        n, psi = self.axis, float(own[0])
        alpha = self.Q.T @ theta_a
        if not exact:
            return alpha + psi * n, np.column_stack([self.Q.T, n])
        D = 1.0 - psi * (alpha @ n) / 4.0
        N = alpha + psi * n + 0.5 * psi * np.cross(alpha, n)
        d_alpha = (np.eye(3) - 0.5 * psi * _skew(n)) / D + np.outer(N, n) * psi / (4 * D * D)
        d_psi = (n + 0.5 * np.cross(alpha, n)) / D + N * (alpha @ n) / (4 * D * D)
        return N / D, np.column_stack([d_alpha @ self.Q.T, d_psi])

    def parameters(self, theta_a, theta_b, exact: bool = True) -> np.ndarray:
        """psi fitted to theta_a, theta_b: the n part of c(alpha)^-1 c(theta_b)."""
        alpha = self.Q.T @ theta_a
        if not exact:
            return np.array([self.axis @ (theta_b - alpha)])
        turn = np_qmul(np.concatenate([[2.0], -alpha]), np.concatenate([[2.0], theta_b]))
        return np.array([2.0 * (self.axis @ turn[1:]) / turn[0]])


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
        q_a0, q_b0 = (placed_shape(rods[m], [node * rods[m].params.length / rods[m].n_cells])[1][0]
                      for m, node in ((i, node_a), (j, node_b)))
        relative = np_rotation_matrix(np_qmul(q_a0 * _CONJ, q_b0))
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


class JointReactions:
    """The force and couple of each joint on its second rod (see module), between steps
    (rotation increments 0)."""

    def __init__(self, model, joints: list[Joint], nodes):
        self.model = model
        self.names = [joint_label(joint) for joint in joints]
        self.s_nodes = [s_b for _, s_b in nodes]
        unk = model.unknowns
        self.blocks = ("displacement", unk.rotation)
        self.nodes = {b: NodeValues(unk.spaces[b], self.s_nodes) for b in self.blocks}
        self.rotations = NodeValues(unk.chart.q_n.function_space, self.s_nodes)
        self.forms = None        # compiled at the first call (a model only stepped: never)

    def __call__(self) -> dict:
        if self.forms is None:
            self.forms = {b: fem.form(near_nodes(self.model.residual[b], self.model.mesh,
                                                 self.s_nodes)) for b in self.blocks}
        force, moment = (nodal_residual(self.forms[b], self.nodes[b]) for b in self.blocks)
        q = self.rotations(self.model.unknowns.chart.q_n.x.array)
        out = {}
        for name, f, m, q_node in zip(self.names, force, moment, q):
            couple = spatial_rotations(self.blocks[1], q_node) @ m
            out.update({f"joint_{name}_force_{c}": f[i] for i, c in enumerate("xyz")})
            out.update({f"joint_{name}_couple_{c}": couple[i] for i, c in enumerate("xyz")})
        return out
