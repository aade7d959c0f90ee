"""Weak forms of the balance of linear and angular momentum (eqs. linmom, angmom).

Tested with a virtual displacement dx and a virtual rotation (material components
dTheta = 2 vec(conj(q) dq)/|q|^2, spatial dtheta = R dTheta), the balance laws

    (rho A) r_tt = n_s + f,                                   (eq. linmom)
    d/dt[(rho J) w] = m_s + r_s x n + l,                      (eq. angmom)

become, after integration by parts and with material components m = R^T m, n = R^T n,

    int [rhoA r_tt . dx + (J W_t + W x J W) . dTheta + m . du + n . dv] ds
        = int [f . dx + l . dtheta] ds + [end forces . dx + end couples . dtheta]_ends,

since du = delta u and dv = delta v are the variations of the material strains
(delta v = R^T dx_s - dTheta x v, delta u = dTheta_s + u x dTheta), and
(rho J) w = R J W with J = diag(I22, I11, I11 + I22) gives d/dt[(rho J) w] = R(J W_t +
W x J W).  Second order in time is written first order: velocity V and material angular
velocity W are fields with the kinematic equations x_t = V, W = 2 vec(conj(q) q_t)/|q|^2
holding at the vertices (vertex quadrature, as torsion.py's angular velocity).
"""

from __future__ import annotations

import ufl

from ..fem.gathered_form import GatheredForm
from .rotations import material_derivative_vector, rotation_matrix


def virtual_rotation(q, dq):
    """Material virtual rotation dTheta = 2 vec(conj(q) dq)/|q|^2."""
    return material_derivative_vector(q, dq)


def internal_work(m, n, u, v, fields, tests, dx):
    """int m . delta u + n . delta v ds, with delta u, delta v by ufl.derivative: a block
    residual's first terms, gathered (more terms are added to it; fem/gathered_form.py)."""
    du = sum(ufl.derivative(u, f, w) for f, w in zip(fields, tests))
    form = GatheredForm()
    form.integrate(ufl.inner(m, du), dx)
    if n is not None:
        dv = sum(ufl.derivative(v, f, w) for f, w in zip(fields, tests))
        form.integrate(ufl.inner(n, dv), dx)
    return form


def inertia(rho_A, J, velocity_rate, W, W_rate, x_test, dTheta, dx):
    """The left sides of eqs. linmom and angmom, tested: the (displacement, quaternion)
    blocks int rhoA V_t . dx ds and int (J W_t + W x J W) . dTheta ds."""
    return (rho_A * ufl.inner(velocity_rate, x_test) * dx,
            ufl.inner(ufl.dot(J, W_rate) + ufl.cross(W, ufl.dot(J, W)), dTheta) * dx)


def kinematic_equations(x_rate, V, q, q_rate, W, V_test, W_test, dx_vertex):
    """x_t = V and W = 2 vec(conj(q) q_t)/|q|^2 nodally: (velocity, angular velocity) blocks."""
    return (ufl.inner(x_rate - V, V_test) * dx_vertex,
            ufl.inner(W - material_derivative_vector(q, q_rate), W_test) * dx_vertex)


def gauge(q, lam, q_test, lam_test, dx_vertex):
    """|q| = 1 at the vertices, multiplier lam: the (quaternion, multiplier) blocks of the
    variation of int lam (|q|^2 - 1)/2 ds."""
    return (lam * ufl.inner(q, q_test) * dx_vertex,
            0.5 * (ufl.inner(q, q) - 1.0) * lam_test * dx_vertex)


def force_work(force, q, x_test, follower: bool):
    """Virtual work density of a force: dead (spatial F) or follower (material F, R F)."""
    f = ufl.dot(rotation_matrix(q), force) if follower else force
    return ufl.inner(f, x_test)


def couple_work(couple, q, dTheta, follower: bool):
    """Virtual work density of a couple: dead (spatial C . R dTheta) or follower (C . dTheta)."""
    c = couple if follower else ufl.dot(ufl.transpose(rotation_matrix(q)), couple)
    return ufl.inner(c, dTheta)
