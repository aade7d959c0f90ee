"""Strains of a special Cosserat rod in the material frame (Section 2.1, Section 4).

Configuration: centre line r(s) = X(s) + x(s) (reference centre line X, displacement x)
and rotation R(s) = R(q/|q|) of a quaternion field q, d_k = R e_k (eq. rotdir).

    v = R^T d_s r                       (sans-serif v: shear v_1, v_2 and dilation v_3)
    u = axial(R^T d_s R)                (sans-serif u: flexure u_1, u_2 and twist u_3)
      = 2 vec(conj(q) q_s)/|q|^2

The natural/elastic split (eqs. ustraindecomp, vstraindecomp) is u = u_d + u_e,
v = v_d + v_e, with u_d, v_d the natural strains (fields of the model).  Strain rates
are directional derivatives along the rates of the fields, so they are consistent with
the strains for any time scheme.
"""

from __future__ import annotations

import ufl

from .rotations import material_derivative_vector, rotation_matrix


def material_curvature(q):
    """u = axial(R^T R_s) from a quaternion field q (any |q| != 0)."""
    return material_derivative_vector(q, q.dx(0))


def material_stretch(q, r_s):
    """v = R^T r_s."""
    return ufl.dot(ufl.transpose(rotation_matrix(q)), r_s)


def strains(x, q, X_s):
    """(u, v) from displacement x, quaternion q and reference tangent X_s = dX/ds."""
    return material_curvature(q), material_stretch(q, X_s + x.dx(0))


def strain_rates(u, v, fields, rates):
    """(du/dt, dv/dt) as derivatives of u, v along (x_t, q_t) (exact for q, x fields)."""
    u_t = sum(ufl.derivative(u, f, r) for f, r in zip(fields, rates))
    v_t = sum(ufl.derivative(v, f, r) for f, r in zip(fields, rates))
    return u_t, v_t

