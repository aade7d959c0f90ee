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

import numpy as np

from ..fem import form_cache
from ..fem.multipoint import NodeLink, NodeMap
from ..fem.fe_model import NodeValues, near_nodes, nodal_residual
from ..theory.quaternions import CONJ, np_qmul, np_rotation_matrix
from .boundary_conditions import spatial_rotations
from .initial_state import stress_free
from .joint_points import Joint, joint_label, locate

def joint_nodes(model, joints: list[Joint]) -> list[tuple[float, float]]:
    """(s of the first rod's node, s of the second rod's node) on the system's mesh at
    each joint (``locate``)."""
    layout = model.layout
    starts, h = layout.starts, [L / n for L, n in zip(layout.lengths, layout.n_cells)]
    return [(starts[k_a] + i_a * h[k_a], starts[k_b] + i_b * h[k_b])
            for k_a, i_a, k_b, i_b in locate(model.rods, joints)]


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
            relative = np_rotation_matrix(np_qmul(q_a * CONJ, q_b))
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
            self.Q = np_rotation_matrix(np_qmul(q_a * CONJ, q_b))

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

    def curvature(self, theta_a, own) -> np.ndarray:
        """d^2 theta_b / d(theta_a, psi)^2 of the exact map (3 x 4 x 4, symmetric in its
        last two indices): of N/D with x = (alpha, psi), N_x = [I - psi/2 [n]x, n + alpha
        x n/2], D_x = -(psi n, alpha.n)/4, whose only second derivatives are the mixed
        alpha_j psi ones, N: -[n]x e_j/2, D: -n_j/4; then alpha = Q^T theta_a."""
        n, psi = self.axis, float(own[0])
        alpha = self.Q.T @ theta_a
        D = 1.0 - psi * (alpha @ n) / 4.0
        N = alpha + psi * n + 0.5 * psi * np.cross(alpha, n)
        dN = np.column_stack([np.eye(3) - 0.5 * psi * _skew(n), n + 0.5 * np.cross(alpha, n)])
        dD = np.append(-psi * n / 4.0, -(alpha @ n) / 4.0)
        ddN, ddD = np.zeros((3, 4, 4)), np.zeros((4, 4))
        ddN[:, :3, 3] = ddN[:, 3, :3] = -0.5 * _skew(n)
        ddD[:3, 3] = ddD[3, :3] = -n / 4.0
        cross = np.einsum("ik,l->ikl", dN, dD)
        H = (ddN / D - (cross + cross.transpose(0, 2, 1)) / D ** 2
             - np.einsum("i,kl->ikl", N, ddD) / D ** 2
             + 2.0 * np.einsum("i,k,l->ikl", N, dD, dD) / D ** 3)
        T = np.eye(4)
        T[:3, :3] = self.Q.T
        return np.einsum("ikl,ka,lb->iab", H, T, T)

    def parameters(self, theta_a, theta_b, exact: bool = True) -> np.ndarray:
        """psi fitted to theta_a, theta_b: the n part of c(alpha)^-1 c(theta_b)."""
        alpha = self.Q.T @ theta_a
        if not exact:
            return np.array([self.axis @ (theta_b - alpha)])
        turn = np_qmul(np.concatenate([[2.0], -alpha]), np.concatenate([[2.0], theta_b]))
        return np.array([2.0 * (self.axis @ turn[1:]) / turn[0]])


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
            self.forms = {b: form_cache.jit_form(near_nodes(
                self.model.residual[b], self.model.mesh, self.s_nodes)) for b in self.blocks}
        force, moment = (nodal_residual(self.forms[b], self.nodes[b]) for b in self.blocks)
        q = self.rotations(self.model.unknowns.chart.q_n.x.array)
        out = {}
        for name, f, m, q_node in zip(self.names, force, moment, q):
            couple = spatial_rotations(self.blocks[1], q_node) @ m
            out.update({f"joint_{name}_force_{c}": f[i] for i, c in enumerate("xyz")})
            out.update({f"joint_{name}_couple_{c}": couple[i] for i, c in enumerate("xyz")})
        return out
