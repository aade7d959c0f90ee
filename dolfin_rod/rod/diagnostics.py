"""The rod's diagnostic forms: free and kinetic energy, dissipation rate (eq. disspw, with
drag), power of the loads; the tip position and quaternion (nodal values) and the tip
rotation angle."""

from __future__ import annotations

import functools

import numpy as np
import ufl

from ..theory.dissipation import dissipation_rate
from ..fem.fe_model import NodeValues
from ..theory.rotations import np_qmul, np_rotation_angle, rotation_matrix
from .rotation_vector import np_cayley


def dissipation_density(resp, c: dict, natural_pairs: list):
    """xi (eq. disspw) from the Kelvin-Voigt strain rates and the natural-strain pairs."""
    viscous = ([(resp.u_t, c["M"])] if "M" in c else []) + (
        [(resp.v_t, c["N"])] if "N" in c and resp.n is not None else [])
    if viscous or natural_pairs:
        return dissipation_rate(viscous, natural_pairs)
    return 0 * resp.psi


def energy_forms(resp, xi, c: dict, unk, disc, power, drag_dissipation,
                 support_energy=0) -> dict:
    """free_energy (with the springs' energy of compliant supports), dissipation_rate,
    kinetic_energy, load_power; a dynamic rod's momenta too (momentum_forms)."""
    dx_r = disc.dx_r
    forms = {"free_energy": resp.psi * dx_r + support_energy,
             "dissipation_rate": xi * dx_r + drag_dissipation,
             "kinetic_energy": _kinetic(resp, c, unk, disc),
             "load_power": 0 * resp.psi * dx_r + power}
    if unk.dynamic:
        forms.update(momentum_forms(c, unk, disc))
    return forms


def momentum_forms(c: dict, unk, disc) -> dict:
    """The rod's linear momentum p = int rhoA r_t ds (momentum_{xyz}) and angular momentum
    about the origin h = int (r x rhoA r_t + R (rho J) w) ds (angular_momentum_{xyz}),
    spatial components: r = s e_3 + x the centre line, r_t = V, w = W the angular
    velocity in the material frame; the inertia's measure (eqs. linmom, angmom: p_t and
    h_t are the resultant force and moment of the loads about the origin)."""
    V, W = unk.V, unk.W
    s = ufl.SpatialCoordinate(disc.mesh)[0]
    r = ufl.as_vector((0.0, 0.0, s)) + unk.f["displacement"]
    p = c["rho_A"] * V
    h = ufl.cross(r, p) + ufl.dot(rotation_matrix(unk.q), ufl.dot(c["J"], W))
    return {**{f"momentum_{a}": p[i] * disc.dx for i, a in enumerate("xyz")},
            **{f"angular_momentum_{a}": h[i] * disc.dx for i, a in enumerate("xyz")}}


def _kinetic(resp, c: dict, unk, disc, chi=None):
    """The kinetic energy's form (on the part of indicator chi, if given; 0
    quasi-static)."""
    if not unk.dynamic:
        return 0 * resp.psi * disc.dx_r
    V, W = unk.V, unk.W
    kinetic = 0.5 * (c["rho_A"] * ufl.inner(V, V) + ufl.inner(W, ufl.dot(c["J"], W)))
    return (kinetic if chi is None else chi * kinetic) * disc.dx


def rod_energy_forms(name: str, resp, c: dict, unk, disc, chi, support_energy=0) -> dict:
    """One rod's free energy (with its springs) and kinetic energy, ``<name>.<key>``, on
    its indicator chi (layout.Pieces.indicator)."""
    return {f"{name}.free_energy": chi * resp.psi * disc.dx_r + support_energy,
            f"{name}.kinetic_energy": _kinetic(resp, c, unk, disc, chi)}


class Tip:
    """tip_position_{xyz} (r = s_tip e_3 + x) and tip_quaternion_{0..3} at the tip node
    s = s_tip (a rod's right end: L, or its end on a system's mesh): nodal values
    (rotation vectors: q_n c(theta) of the tip node only).  The tip's dofs are looked up
    at the first call (~0.3 ms of a model's set-up that a run without diagnostics, such
    as a benchmark's or a fit's, does not need)."""

    def __init__(self, unk, s_tip: float):
        self.unk, self.length = unk, s_tip

    @functools.cached_property
    def x_node(self) -> NodeValues:
        return NodeValues(self.unk.f["displacement"].function_space, [self.length])

    @functools.cached_property
    def q_node(self) -> NodeValues:
        unk = self.unk
        q = unk.f["quaternion"] if unk.chart is None else unk.chart.q_n
        return NodeValues(q.function_space, [self.length])

    @functools.cached_property
    def theta_node(self) -> NodeValues | None:
        unk = self.unk
        return (None if unk.chart is None else
                NodeValues(unk.f[unk.rotation].function_space, [self.length]))

    def __call__(self) -> dict:
        unk = self.unk
        x = self.x_node(unk.f["displacement"].x.array)[0]
        if unk.chart is None:
            q = self.q_node(unk.f["quaternion"].x.array)[0]
        else:       # NodeValues sums over the ranks: the owner's values
            theta = self.theta_node(unk.f[unk.rotation].x.array)
            q = np_qmul(self.q_node(unk.chart.q_n.x.array), np_cayley(theta))[0]
        d = {f"tip_position_{c}": x[i] for i, c in enumerate("xyz")}
        d["tip_position_z"] += self.length
        d.update({f"tip_quaternion_{i}": q[i] for i in range(4)})
        return d


class PointPositions:
    """point{j}_position_{xyz} (r = s e_3 + x, as Tip's) at the j-th distinct point s of
    the point loads (P1: the two nodes around s weighted by their hat functions there).
    points: (start a_k of its rod on the mesh, h of its rod, its own s) triples."""

    def __init__(self, unk, points):
        self.unk, self.samples = unk, []
        space = unk.f["displacement"].function_space
        for a, h, s in points:
            i = int(round(s / h)) if abs(s / h - round(s / h)) < 1e-9 else int(s // h)
            weight = max(s / h - i, 0.0)        # of the node above: 0 at a node
            nodes = [a + i * h] + ([a + (i + 1) * h] if weight else [])
            weights = [1.0 - weight] + ([weight] if weight else [])
            self.samples.append((NodeValues(space, nodes), np.array(weights), a + s))

    def __call__(self) -> dict:
        d = {}
        for j, (nodes, weights, s) in enumerate(self.samples):
            x = weights @ nodes(self.unk.f["displacement"].x.array) + np.array([0.0, 0.0, s])
            d.update({f"point{j}_position_{c}": x[i] for i, c in enumerate("xyz")})
        return d


def tip_rotation_angle(d: dict) -> float:
    """Angle of the tip rotation path, in [0, 2 pi], from the tip quaternion."""
    return np_rotation_angle([d[f"tip_quaternion_{i}"] for i in range(4)])
