"""Rotation unknowns of a dynamic rod: an incremental rotation vector on stored nodal unit
quaternions (6 unknowns per node, no gauge multiplier, no saddle point).

Per node the rotation is q_a = q_n,a c(theta_a): q_n,a a stored unit quaternion (P1,
4 components, not an unknown), theta_a the unknown material rotation increment of the
current step, c the normalised Cayley map

    c(theta) = (2, theta) / sqrt(4 + |theta|^2)    (angle 2 atan(|theta|/2), unit),

and after each accepted step q_n <- q_n c(theta), theta <- 0 (``commit``).  The strains
are those of the quaternion discretisation (kinematics.py: the P1 interpolant q of the
nodal quaternions, u = 2 vec(conj(q) q_s)/|q|^2 and v = R(q)^T r_s at the cell midpoint),
written with m = 2 |k_a| conj(q_n,a) q_mid and d = h |k_a| conj(q_n,a) q_s (``strains``;
k = (2, theta), c = k/|k|; both strains are homogeneous of degree 0 in (m, d)):

    u = 4 vec(conj(m) d) / (h |m|^2),    v = R(m)^T R(q_n,a)^T r_s,

where in 1-D the nodal values of a P1 field are UFL expressions at any point of the cell,
f_a = f(s) + (s_a - s) f_s(s), and q_n,a, p_n = conj(q_n,a) q_n,b are per-cell (DG0)
data refreshed at each commit.  The strains depend only on the current nodal unit
quaternions: objectivity (q -> q_Q q) and path independence are exact.

A virtual rotation of the unknown, delta theta, is the material virtual rotation
dTheta = T(theta) delta theta with T(theta) = 4/(4 + |theta|^2) (I - [theta]x/2)
(derivative of the Cayley map; T(0) = I between steps, when diagnostics run).  Strain rates
(Kelvin-Voigt) are the derivatives of the strains along the nodal material angular
velocities W: q_a c(eta_a) with eta = 0 a fixed zero field and d/d eta in the direction W.
"""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import ufl

from ..kinematics import strain_rates
from ..rotations import np_qmul, qmul, rotation_matrix, vec

E3 = ufl.as_vector((0.0, 0.0, 1.0))


def cayley(theta):
    """Unit quaternion of the rotation vector theta by the normalised Cayley map (UFL)."""
    return _k(theta) / ufl.sqrt(4.0 + ufl.dot(theta, theta))


def np_cayley(theta):
    theta = np.asarray(theta, dtype=float)
    q = np.concatenate([np.full(theta.shape[:-1] + (1,), 2.0), theta], axis=-1)
    return q / np.sqrt(4.0 + np.sum(theta * theta, axis=-1))[..., None]


def np_inverse_cayley(q):
    """theta with c(theta) = +-q: theta = 2 vec(q)/q_0 (rotations by less than pi)."""
    q = np.asarray(q, dtype=float)
    return 2.0 * q[..., 1:] / q[..., :1]


def tangent(theta, dtheta):
    """Material rotation 2 vec(conj(c) dc) of an increment dtheta at theta: T(theta) dtheta."""
    return 4.0 / (4.0 + ufl.dot(theta, theta)) * (dtheta - 0.5 * ufl.cross(theta, dtheta))


def _RT(q):
    return ufl.transpose(rotation_matrix(q))


def rotate_back(m, y):
    """R(m/|m|)^T y for any quaternion m != 0: y + 2 (mv x (mv x y) - m_0 mv x y)/|m|^2."""
    mv = vec(m)
    c = ufl.cross(mv, y)
    return y + 2.0 / ufl.dot(m, m) * (ufl.cross(mv, c) - m[0] * c)


def strains(k_a, k_b, r_s, q_n_a, p_n, h):
    """(u, v) of one cell: the strains of the P1 quaternion interpolant at the midpoint,
    q_mid = (q_a + q_b)/2, for the nodal rotations q_a = q_n,a k_a/|k_a|,
    q_b = q_n,b k_b/|k_b| (k_a, k_b quaternions of any norm: k = (2, theta) for the
    Cayley map; q_n,a and p_n = conj(q_n,a) q_n,b unit, per cell; h the cell length).
    With m = k_a + (|k_a|/|k_b|) p_n k_b = 2 |k_a| conj(q_n,a) q_mid and
    d = (|k_a|/|k_b|) p_n k_b - k_a = h |k_a| conj(q_n,a) q_s:

        u = 2 vec(conj(q_mid) q_s)/|q_mid|^2 = 4 vec(conj(m) d)/(h |m|^2),
        v = R(q_mid)^T r_s = R(m)^T R(q_n,a)^T r_s.

    One square root, one quaternion product, one rotation of the unknowns: the Jacobian
    kernel (the second derivative of this graph) has 14.1k flops against 27.2k for
    p = conj(c_a) p_n c_b, u = 4 vec(p)/(h (1 + p_0)), v = R(1 + p)^T R(c_a)^T R(q_n,a)^T r_s
    (same strains to round-off; docs/performance.md).
    """
    pk_b = ufl.sqrt(ufl.dot(k_a, k_a) / ufl.dot(k_b, k_b)) * qmul(p_n, k_b)
    m, d = k_a + pk_b, pk_b - k_a
    mv, dv = vec(m), vec(d)
    u = 4 * (m[0] * dv - d[0] * mv - ufl.cross(mv, dv)) / (h * ufl.dot(m, m))
    return u, rotate_back(m, ufl.dot(_RT(q_n_a), r_s))


def _k(theta):
    """(2, theta): the Cayley map before its normalisation, c(theta) = k/|k|."""
    return ufl.as_vector((2.0, theta[0], theta[1], theta[2]))


class RotationVectorChart:
    """Stored nodal rotations q_n of a rod mesh and the strains of q_n c(theta).

    theta: the rotation-increment Function (P1, 3); body_rates: build the strain rates
    along the material angular velocities (Kelvin-Voigt viscosity)."""

    def __init__(self, mesh, theta: fem.Function):
        self.mesh, self.theta = mesh, theta
        self.s_mid = fem.Function(fem.functionspace(mesh, ("DG", 0)), name="cell_midpoint")
        self.s_mid.interpolate(lambda X: X[0])
        Q = fem.functionspace(mesh, ("Lagrange", 1, (4,)))
        tdim = mesh.topology.dim
        ncell = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
        nodes = Q.dofmap.list[:ncell]
        sx = Q.tabulate_dof_coordinates()[:, 0]
        swap = sx[nodes[:, 0]] > sx[nodes[:, 1]]
        self.node_s = sx
        self.q_n = fem.Function(Q, name="stored_rotation")
        self._cell_nodes = (np.where(swap, nodes[:, 1], nodes[:, 0]),
                            np.where(swap, nodes[:, 0], nodes[:, 1]))
        S4 = fem.functionspace(mesh, ("DG", 0, (4,)))
        self.qa_n = fem.Function(S4, name="stored_rotation_left")
        self.p_n = fem.Function(S4, name="stored_relative_rotation")
        self.eta = fem.Function(theta.function_space, name="body_rate_perturbation")
        self.q = qmul(self.q_n, cayley(theta))          # q at any point (loads, tip, R)

    def strains(self, x, body_rates: bool = False):
        """(u, v) at the cell midpoint from the nodal q_a = q_n,a c(theta_a) (c(eta_a))."""
        s, h = ufl.SpatialCoordinate(self.mesh)[0], ufl.CellVolume(self.mesh)

        def nodal(f, s_node):
            return f + (s_node - s) * f.dx(0)

        ends = (self.s_mid - h / 2, self.s_mid + h / 2)
        k_a, k_b = (_k(nodal(self.theta, e)) for e in ends)
        if body_rates:
            k_a, k_b = (qmul(k, _k(nodal(self.eta, e))) for k, e in zip((k_a, k_b), ends))
        return strains(k_a, k_b, E3 + x.dx(0), self.qa_n, self.p_n, h)

    def strain_rates(self, u, v, x, V, W):
        """(u_t, v_t) along the velocity V and material angular velocity W (nodal)."""
        return strain_rates(u, v, [x, self.eta], [V, W])

    def virtual_rotation(self, dtheta):
        return tangent(self.theta, dtheta)

    def commit(self) -> None:
        """q_n <- q_n c(theta) nodally, theta <- 0 (after an accepted step)."""
        th = self.theta.x.array.reshape(-1, 3)
        qn = np_qmul(self.q_n.x.array.reshape(-1, 4), np_cayley(th))
        th[:] = 0.0
        self.set_nodal_rotations(qn / np.linalg.norm(qn, axis=1)[:, None])

    def set_nodal_rotations(self, q) -> None:
        """q_n := q (rows for local + ghost nodes, or a callable of the nodes' s), and
        per cell the left node's q_n,a and p_n = conj(q_n,a) q_n,b."""
        qn = self.q_n.x.array.reshape(-1, 4)
        qn[:] = q(self.node_s) if callable(q) else q
        left, right = self._cell_nodes
        self.qa_n.x.array.reshape(-1, 4)[:] = qn[left]
        self.p_n.x.array.reshape(-1, 4)[:] = np_qmul(qn[left] * [1, -1, -1, -1], qn[right])

    def refresh(self) -> None:
        """Per-cell data from q_n as it is (after q_n was read from a checkpoint)."""
        self.set_nodal_rotations(self.q_n.x.array.reshape(-1, 4).copy())
