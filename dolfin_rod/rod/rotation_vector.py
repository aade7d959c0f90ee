"""Rotation unknowns of a dynamic rod: an incremental rotation vector on stored nodal unit
quaternions (6 unknowns per node, no gauge multiplier, no saddle point).

Per node the rotation is q_a = q_n,a c(theta_a): q_n,a a stored unit quaternion (P1,
4 components, not an unknown), theta_a the unknown material rotation increment of the
current step, c the normalised Cayley map

    c(theta) = (2, theta) / sqrt(4 + |theta|^2)    (angle 2 atan(|theta|/2), unit),

and after each accepted step q_n <- q_n c(theta), theta <- 0 (``commit``).  The strains
are those of the quaternion discretisation (kinematics.py: the P1 interpolant q of the
nodal quaternions, u = 2 vec(conj(q) q_s)/|q|^2 and v = R(q)^T r_s at the cell midpoint),
written with the relative rotation p = conj(q_a) q_b of the cell:

    u = 4 vec(p) / (h (1 + p_0)),    v = R(1 + p)^T R(q_a)^T r_s,

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
from ..rotations import conj, np_qmul, qmul, rotation_matrix, vec

E3 = ufl.as_vector((0.0, 0.0, 1.0))


def cayley(theta):
    """Unit quaternion of the rotation vector theta by the normalised Cayley map (UFL)."""
    return (ufl.as_vector((2.0, theta[0], theta[1], theta[2]))
            / ufl.sqrt(4.0 + ufl.dot(theta, theta)))


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
        c_a, c_b = (cayley(nodal(self.theta, e)) for e in ends)
        if body_rates:
            c_a, c_b = (qmul(c, cayley(nodal(self.eta, e))) for c, e in zip((c_a, c_b), ends))
        p = qmul(qmul(conj(c_a), self.p_n), c_b)          # conj(q_a) q_b
        # q_mid = (q_a + q_b)/2 = q_a (1 + p)/2 (module docstring)
        u = 4 * vec(p) / (h * (1 + p[0]))
        one_p = ufl.as_vector((1 + p[0], p[1], p[2], p[3]))
        v = ufl.dot(_RT(one_p), ufl.dot(_RT(c_a), ufl.dot(_RT(self.qa_n), E3 + x.dx(0))))
        return u, v

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
