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
f_a = f(s) + (s_a - s) f_s(s) (also for q_n,a, q_n,b and p_n = conj(q_n,a) q_n,b).
The strains depend only on the current nodal unit quaternions: objectivity (q -> q_Q q)
and path independence are exact.

A virtual rotation of the unknown, delta theta, is the material virtual rotation
dTheta = T(theta) delta theta with T(theta) = 4/(4 + |theta|^2) (I - [theta]x/2)
(derivative of the Cayley map; T(0) = I between steps, when diagnostics run).  Strain rates
(Kelvin-Voigt) are the derivatives of the strains along the nodal material angular
velocities W: q_a c(eta_a) with eta = 0 a fixed zero field and d/d eta in the direction W.
"""

from __future__ import annotations

import functools
import math

import dolfinx.fem as fem
import numpy as np
import ufl

from ufl.corealg.traversal import unique_pre_traversal

from ..fem import shared_mesh
from ..mpi import largest_on_ranks
from ..theory.kinematics import strain_rates
from ..theory.rotations import conj, np_qmul, qmul, rotation_matrix, vec

E3 = ufl.as_vector((0.0, 0.0, 1.0))
GAUSS_2 = 0.5 / np.sqrt(3.0)     # the 2-point Gauss points: s_mid -+ GAUSS_2 h
MAX_INCREMENT = 2.0              # |theta| of a rotation by pi/2 per step (check_increment)
# max_i |theta_i| below which |theta| <= sqrt(3) max_i |theta_i| is below MAX_INCREMENT by
# far more than round-off
_INCREMENT_BOUND = MAX_INCREMENT * (1.0 - 1e-9) / math.sqrt(3.0)
_INCREMENT_BOUND_SQUARED = (MAX_INCREMENT * (1.0 - 1e-9)) ** 2


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
    Cayley map; q_n,a and p_n = conj(q_n,a) q_n,b unit, fixed in a step; h the cell
    length).
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


def _linear_fields(g) -> list | None:
    """The arguments and coefficients of g of degree 1 on a cell, in the order of
    extract_arguments + extract_coefficients (the order in which their values at a point
    are built decides the form's index numbering, so its signature), or None if g has
    derivatives or a field of higher degree: one traversal of g instead of three."""
    arguments, coefficients = [], []
    for node in unique_pre_traversal(g):
        if isinstance(node, ufl.classes.Derivative):
            return None
        if isinstance(node, (ufl.Argument, ufl.Coefficient)):
            degree = node.ufl_element().embedded_superdegree
            if degree > 1:
                return None
            if degree == 1:
                (arguments if isinstance(node, ufl.Argument) else coefficients).append(node)
    return (sorted(arguments, key=lambda a: a.number())
            + sorted(coefficients, key=lambda c: c.count()))


def _k(theta):
    """(2, theta): the Cayley map before its normalisation, c(theta) = k/|k|."""
    return ufl.as_vector((2.0, theta[0], theta[1], theta[2]))


def _midpoints(mesh) -> tuple:
    """(the DG0 space of ``mesh``, the cells' midpoints s in its dof order, ghosts too)."""
    space = fem.functionspace(mesh, ("DG", 0))
    s_mid = fem.Function(space)
    s_mid.interpolate(lambda X: X[0])
    return space, s_mid.x.array.copy()


class RotationVectorChart:
    """Stored nodal rotations q_n of a rod mesh and the strains of q_n c(theta).

    theta: the rotation-increment Function (P1, 3); body_rates: build the strain rates
    along the material angular velocities (Kelvin-Voigt viscosity)."""

    def __init__(self, mesh, theta: fem.Function):
        self.mesh, self.theta = mesh, theta
        # the midpoints' space and values, interpolated once per kept mesh (a second
        # model copies them: DOLFINx's interpolation of a callable costs ~50 us)
        space, values = shared_mesh.space(mesh, "cell midpoints", lambda: _midpoints(mesh))
        self.s_mid = fem.Function(space, name="cell_midpoint")
        self.s_mid.x.array[:] = values
        Q = shared_mesh.space(mesh, "stored rotations", lambda: fem.functionspace(
            mesh, ("Lagrange", 1, (4,))))
        self.node_s = Q.tabulate_dof_coordinates()[:, 0]
        self.q_n = fem.Function(Q, name="stored_rotation")
        self.eta = fem.Function(theta.function_space, name="body_rate_perturbation")
        # views of the arrays commit() updates after every step (fetched once)
        self._theta = theta.x.array
        self._theta_nodes = self._theta.reshape(-1, 3)
        self._q_nodes = self.q_n.x.array.reshape(-1, 4)
        self._k = np.full((len(self._theta_nodes), 4), 2.0)

    @functools.cached_property
    def q(self):
        """q at any point (loads, tip, R): UFL, made at the first read."""
        return qmul(self.q_n, cayley(self.theta))

    def strains(self, x, body_rates: bool = False):
        """(u, v) at the cell midpoint from the nodal q_a = q_n,a c(theta_a) (c(eta_a))."""
        h = ufl.CellVolume(self.mesh)
        ends = (self.s_mid - h / 2, self.s_mid + h / 2)
        k_a, k_b = (_k(self._value_at(self.theta, e)) for e in ends)
        if body_rates:
            k_a, k_b = (qmul(k, _k(self._value_at(self.eta, e))) for k, e in zip((k_a, k_b),
                                                                                   ends))
        q_a, q_b = (self._value_at(self.q_n, e) for e in ends)
        return strains(k_a, k_b, E3 + x.dx(0), q_a, qmul(conj(q_a), q_b), h)

    def _value_at(self, f, s_point):
        """f(s_point) for a field f linear on the cell, as a UFL expression at any point s
        of the cell: f + (s_point - s) f_s."""
        return f + (s_point - ufl.SpatialCoordinate(self.mesh)[0]) * f.dx(0)

    def one_point_rule(self, integrals, dx_r: ufl.Measure) -> ufl.Form:
        """The form of ``integrals`` with its 2-point Gauss integrals (inertia, loads, drag)
        written as 1-point integrals of (g(s_1) + g(s_2))/2, s_1,2 = s_mid -+ h/(2 sqrt 3):
        the same quadrature (to round-off), so that the step's residual and Jacobian are
        one kernel each (docs/performance.md: one assembly call instead of two).  g(s_k)
        replaces each field f of degree <= 1 on the cell (P1, DG0) by f(s_k)
        (``_value_at``: exact) and s by s_k; an integral whose integrand has derivatives
        or other data stays, and so does a vertex-rule integral (point loads: nodal)."""
        out = []
        for itg in integrals:
            g = itg.integrand()
            linear = (_linear_fields(g) if itg.integral_type() == "cell"
                      and itg.metadata() != dx_r.metadata()
                      and itg.metadata().get("quadrature_rule") != "vertex" else None)
            if linear is not None:
                h, x = ufl.CellVolume(self.mesh), ufl.SpatialCoordinate(self.mesh)
                values = []
                for s_k in (self.s_mid - GAUSS_2 * h, self.s_mid + GAUSS_2 * h):
                    mapping = {f: self._value_at(f, s_k) for f in linear}
                    mapping[x] = ufl.as_vector((s_k,))
                    values.append(ufl.replace(g, mapping))
                itg = itg.reconstruct(integrand=0.5 * (values[0] + values[1]),
                                      metadata=dx_r.metadata())
            out.append(itg)
        return ufl.Form(out)

    def strain_rates(self, u, v, x, V, W):
        """(u_t, v_t) along the velocity V and material angular velocity W (nodal)."""
        return strain_rates(u, v, [x, self.eta], [V, W])

    def virtual_rotation(self, dtheta):
        return tangent(self.theta, dtheta)

    def check_increment(self) -> str | None:
        """A reason to redo the step if a node rotated by more than pi/2 in it
        (|theta| > MAX_INCREMENT; the same answer on every rank), else None.  The Cayley
        map reaches rotations near pi only as |theta| -> infinity, and Newton can
        converge there, to a spurious root: a whip at 11 cells took a step with
        |theta| ~ 1e7 (angular velocity 5e8 rad/s) and went on from it.  A resolved
        step rotates far less (the benchmark scenes: < 0.8 rad)."""
        th = self._theta_nodes
        # every node's |theta|^2 <= the sum over the nodes, and |theta| <= sqrt(3) max_i
        # |theta_i|: a rank whose bound is below the limit by far more than round-off
        # computes no norm (after every step; the same answers, NaN too)
        local = 0.0
        if len(th) and not self._theta @ self._theta <= _INCREMENT_BOUND_SQUARED and \
                not np.abs(th).max() <= _INCREMENT_BOUND:
            local = np.sqrt(np.max(np.einsum("ij,ij->i", th, th), initial=0.0))
        largest = largest_on_ranks(self.mesh.comm, local)
        if largest <= MAX_INCREMENT:
            return None
        angle = 2 * np.arctan(largest / 2)
        return f"a node rotated by {angle:.3g} rad in one step (more than pi/2)"

    def commit(self) -> None:
        """q_n <- q_n c(theta) nodally, theta <- 0 (after an accepted step).  With
        k = (2, theta) = |k| c(theta): q_n k / |q_n k| (one product, no square root of
        the map)."""
        th, k = self._theta_nodes, self._k
        k[:, 1:] = th
        qn = np_qmul(self._q_nodes, k)
        th.fill(0.0)
        np.divide(qn, np.sqrt(np.einsum("ij,ij->i", qn, qn))[:, None], out=self._q_nodes)

    def set_nodal_rotations(self, q) -> None:
        """q_n := q (rows for local + ghost nodes, or a callable of the nodes' s)."""
        self._q_nodes[:] = q(self.node_s) if callable(q) else q
