"""Unshearable and inextensible-unshearable rods (Section 4.5) by Lagrange multipliers.

unshearable:               v_1 = v_2 = 0 (and v_d,1 = v_d,2 = 0): the shear forces n_1, n_2
                           are multipliers; v_3 and v_d,3 remain constitutive.
inextensible_unshearable:  v = e_3 (and v_d = e_3, v_e = 0): the whole contact force n is
                           the multiplier; psi depends on (u_d, u) only.

The multiplier is a DG field on the points where the strains are evaluated (the reduced
quadrature of rod/discretisation.py), so each constraint holds pointwise there.
"""

from __future__ import annotations

import ufl

CONSTRAINTS = (None, "unshearable", "inextensible_unshearable")


def check_constraint(name, dynamic: bool = False):
    """The constraint's name; ValueError if unknown, or if given for a dynamic rod."""
    if name not in CONSTRAINTS:
        raise ValueError(f"unknown constraint '{name}' (known: unshearable, "
                         "inextensible_unshearable, or None)")
    if name is not None and dynamic:
        raise ValueError(f"constraint = {name!r} with density > 0: a dynamic rod with "
                         "constraint multipliers is an index-3 DAE, which no integrator "
                         "here solves reliably; use a quasi-static rod (density = 0) or "
                         "stiff shear/axial B instead of the constraint")
    return name


def multiplier_size(name) -> int:
    """Number of multiplier components per point: 0, 2 (n_1, n_2) or 3 (n)."""
    return {None: 0, "unshearable": 2, "inextensible_unshearable": 3}[check_constraint(name)]


def constrained_stretch(v, name):
    """The part of v that enters psi: v, (0, 0, v_3) or None."""
    if name is None:
        return v
    if name == "unshearable":
        return ufl.as_vector((0.0, 0.0, v[2]))
    return None


def constraint_value(v, name):
    """g(v) = 0: (v_1, v_2) or v - e_3."""
    if name == "unshearable":
        return ufl.as_vector((v[0], v[1]))
    return v - ufl.as_vector((0.0, 0.0, 1.0))


def multiplier_force(lam, name):
    """The multiplier as material contact-force components (n_1, n_2, 0) or n."""
    if name == "unshearable":
        return ufl.as_vector((lam[0], lam[1], 0.0))
    return lam
