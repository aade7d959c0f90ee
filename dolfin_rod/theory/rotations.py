"""SO(3) through quaternions in UFL (their numpy twins, for tests, set-up and the
checks that need no UFL, are in quaternions.py and re-exported here).

The rod's rotation field is a nodal quaternion field q = (q0, q1, q2, q3) (scalar part
first) with R = R(q/|q|), i.e. R a = q a conj(q) / |q|^2.  Then (Section 2.1)

    R^T d_s R = skew(u),  u = 2 vec(conj(q) q_s) / |q|^2    (material curvature, sans-serif u)
    R^T d_t R = skew(W),  W = 2 vec(conj(q) q_t) / |q|^2    (material angular velocity)

Both are invariant under q -> rho(s, t) q (the gauge) and under a superposed rigid
rotation q -> q_Q q.  The latter is linear in q, so it commutes with nodal interpolation:
the discrete strains are exactly frame indifferent, and a continuous q field has no
2 pi limit (q and -q are the same rotation; a rod rolled up once has q = -1 at its tip).
No formula here divides by a rotation angle, so small angles need no special case.
"""

from __future__ import annotations

import ufl

from .quaternions import (np_qmul, np_quaternion_from_matrix,  # noqa: F401 (re-exported)
                          np_quaternion_from_rotation_vector, np_rotation_angle,
                          np_rotation_matrix, np_rotation_vector)


def vec(q):
    """Vector part of a quaternion (UFL)."""
    return ufl.as_vector((q[1], q[2], q[3]))


def conj(q):
    return ufl.as_vector((q[0], -q[1], -q[2], -q[3]))


def qmul(p, q):
    """Hamilton product p q (UFL)."""
    p0, pv = p[0], vec(p)
    q0, qv = q[0], vec(q)
    s = p0 * q0 - ufl.dot(pv, qv)
    v = p0 * qv + q0 * pv + ufl.cross(pv, qv)
    return ufl.as_vector((s, v[0], v[1], v[2]))


def rotation_matrix(q):
    """R(q/|q|) as a UFL 3x3 matrix (exact for any q != 0)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    n2 = ufl.dot(q, q)
    return ufl.as_matrix((
        (w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z),
    )) / n2


def material_derivative_vector(q, dq):
    """2 vec(conj(q) dq)/|q|^2: material axial vector of R^T dR for dq = q_s, q_t, delta q."""
    return 2 * vec(qmul(conj(q), dq)) / ufl.dot(q, q)
