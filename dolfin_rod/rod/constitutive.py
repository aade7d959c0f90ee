"""Strains -> free energy and contact couple m and force n (Sections 2.1, 4.1, 4.2).

    u = 2 vec(conj(q) q_s)/|q|^2,  v = R^T r_s                    (Section 2.1, kinematics.py)
    m = dpsi/du + M du/dt,  n = dpsi/dv + N dv/dt                 (eqs. mfmeq, mfneq)

Models by name: "evolving" (the paper's: psi(u_d, v_d, u, v) with evolving natural
strains), "kelvin_voigt" (psi(u_ref, v_ref, u, v), viscosities M, N) and "hyperelastic"
(no viscosity).  Reference strains u_ref, v_ref are the discrete strains of the initial
configuration (DG0, set by the initial state), so an initially curved or twisted rod is
exactly unstressed at t = 0.  The default energy is eq. quadenergy with the natural part
centred there: 1/2 (u_d - u_ref).A_d (u_d - u_ref) + 1/2 (v_d - v_ref).B_d (v_d - v_ref)
(the paper's form for a straight reference, u_ref = 0, v_ref = e_3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl

from ..theory import constraints
from ..theory.energy import derivatives, quadratic_energy
from ..theory.kinematics import strain_rates, strains
from .material import RodParameters, is_zero

MODELS = ("evolving", "kelvin_voigt", "hyperelastic")


def check_model(model: str, params: RodParameters) -> None:
    if model not in MODELS:
        raise ValueError(f"unknown model '{model}' (known: {', '.join(MODELS)})")
    if model == "kelvin_voigt" and is_zero(params.M) and is_zero(params.N):
        raise ValueError("kelvin_voigt needs a viscosity M or N (else use 'hyperelastic')")


def energy_function(params: RodParameters, c: dict, evolving: bool, u_ref, v_ref):
    """psi(u_d, v_d, u, v): the user's energy (checked on UFL 3-vectors) or eq. quadenergy."""
    if params.energy is None:
        if evolving:
            base = quadratic_energy(c["A"], c["A_d"], c["B"], c["B_d"], v_ref=v_ref)
            return lambda ud, vd, u, v: base(ud - u_ref, vd, u - u_ref, v)
        zero = ufl.as_matrix(np.zeros((3, 3)).tolist())
        return quadratic_energy(c["A"], zero, c["B"], zero)
    psi = params.energy
    if not callable(psi):
        raise ValueError("energy must be a callable psi(u_d, v_d, u, v)")
    probe = [ufl.as_vector((0.1, 0.2, 0.3))] * 4
    try:
        val = psi(*probe)
    except Exception as err:  # noqa: BLE001
        raise ValueError(f"energy callable failed on UFL 3-vectors: {err}") from err
    if not isinstance(val, ufl.core.expr.Expr) or ufl.shape(val) != ():
        raise ValueError("energy must return a scalar UFL expression, got "
                         f"shape {getattr(val, 'ufl_shape', type(val))}")
    return psi


@dataclass
class SectionResponse:
    """Strains, natural strains, psi and its derivatives, strain rates, m and n (n is
    None for an inextensible-unshearable rod, whose v enters through the constraint)."""

    u: object
    v: object
    v_eff: object          # the part of v in psi: v, (0, 0, v_3) or None (constraints.py)
    u_d: object
    v_d: object
    psi: object
    dpsi_dud: object
    dpsi_dvd: object
    u_t: object
    v_t: object
    m: object
    n: object


def natural_strains(unk, evolving: bool, constraint, reference, v_eff):
    """(u_d, v_d): the evolving fields, or the reference strains (Kelvin-Voigt)."""
    u_ref, v_ref = reference
    if not evolving:
        return u_ref, None if v_eff is None else constraints.constrained_stretch(v_ref, constraint)
    v_d = unk.f.get("natural_stretch")
    v_d = None if v_d is None else unk.natural_field(v_d)
    if constraint == "unshearable":
        v_d = ufl.as_vector((0.0, 0.0, v_d))
    return unk.natural_field(unk.f["natural_curvature"]), v_d


def _kinematics(unk, viscous: bool):
    """(u, v, u_t, v_t) of the rotation unknowns (discretisation.py); the strain rates are
    derivatives along the rates (quaternions) or the angular velocities (rotation vectors)."""
    x = unk.f["displacement"]
    if unk.chart is not None:
        u, v = unk.chart.strains(x, body_rates=viscous)
        return (u, v, *unk.chart.strain_rates(u, v, x, unk.V, unk.W))
    q = unk.f["quaternion"]
    u, v = strains(x, q, ufl.as_vector((0.0, 0.0, 1.0)))      # reference tangent X_s = e_3
    return (u, v, *strain_rates(u, v, [x, q], [unk.r["displacement"], unk.r["quaternion"]]))


def section_response(unk, c: dict, psi_fn, evolving: bool, constraint,
                     reference, rates: bool = False) -> SectionResponse:
    """Eqs. mfmeq, mfneq from the configuration (x, q) and its rates; ``rates``: the
    strain rates are read beyond the Kelvin-Voigt moments (an active moment's power
    M . u_t), so that rotation vectors need them too."""
    u, v, u_t, v_t = _kinematics(unk, viscous=rates or "M" in c or "N" in c)
    v_eff = constraints.constrained_stretch(v, constraint)
    if v_eff is not None and v_eff is not v:
        v_t = constraints.constrained_stretch(v_t, constraint)
    u_d, v_d = natural_strains(unk, evolving, constraint, reference, v_eff)
    psi, dpsi_du, dpsi_dv, dpsi_dud, dpsi_dvd = derivatives(psi_fn, u_d, v_d, u, v_eff)
    m = dpsi_du + ufl.dot(c["M"], u_t) if "M" in c else dpsi_du
    n = None
    if v_eff is not None:
        n = dpsi_dv + ufl.dot(c["N"], v_t) if "N" in c else dpsi_dv
    return SectionResponse(u, v, v_eff, u_d, v_d, psi, dpsi_dud, dpsi_dvd, u_t, v_t, m, n)
