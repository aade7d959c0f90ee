"""The rod's diagnostic forms: free and kinetic energy, dissipation rate (eq. disspw, with
drag), power of the loads, tip position and quaternion; and the tip rotation angle."""

from __future__ import annotations

import ufl

from ..dissipation import dissipation_rate
from ..rotations import np_rotation_angle


def dissipation_density(resp, c: dict, natural_pairs: list):
    """xi (eq. disspw) from the Kelvin-Voigt strain rates and the natural-strain pairs."""
    viscous = ([(resp.u_t, c["M"])] if "M" in c else []) + (
        [(resp.v_t, c["N"])] if "N" in c and resp.n is not None else [])
    if viscous or natural_pairs:
        return dissipation_rate(viscous, natural_pairs)
    return 0 * resp.psi


def energy_forms(resp, xi, c: dict, unk, disc, power, drag_dissipation) -> dict:
    """free_energy, dissipation_rate, kinetic_energy, load_power, tip_position_{xyz},
    tip_quaternion_{0..3}."""
    V, W, dx_r = unk.V, unk.W, disc.dx_r
    dynamic = unk.dynamic
    kinetic = 0.5 * (c["rho_A"] * ufl.inner(V, V) + ufl.inner(W, ufl.dot(c["J"], W)))
    forms = {"free_energy": resp.psi * dx_r,
             "dissipation_rate": xi * dx_r + drag_dissipation,
             "kinetic_energy": kinetic * disc.dx if dynamic else 0 * resp.psi * dx_r,
             "load_power": 0 * resp.psi * dx_r + power}
    tip = disc.ds_end["right"]
    r_tip = ufl.as_vector((0.0, 0.0, disc.s)) + unk.f["displacement"]
    for i, comp in enumerate("xyz"):
        forms[f"tip_position_{comp}"] = r_tip[i] * tip
    for i in range(4):
        forms[f"tip_quaternion_{i}"] = unk.q[i] * tip
    return forms


def tip_rotation_angle(d: dict) -> float:
    """Angle of the tip rotation path, in [0, 2 pi], from the tip quaternion."""
    return np_rotation_angle([d[f"tip_quaternion_{i}"] for i in range(4)])
