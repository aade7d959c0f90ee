"""The rod's initial state: at rest in the stress-free configuration of the reference
strains (a straight rod along e_3, or the helix/circle of constant reference_curvature),
natural strains equal to the discrete reference strains (uniform variant: their mean)
unless given, rates zero."""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from ..fem import compat
from ..fem.fe_model import ENDS
from ..theory.rotations import np_qmul, np_quaternion_from_rotation_vector, np_rotation_matrix


def helix(s, u0, v0):
    """Stress-free configuration of constant strains: q(s) = exp(s u0/2), r = int R v0."""
    u0, v0 = np.asarray(u0, float), np.asarray(v0, float)
    a = np.linalg.norm(u0)
    U = np.array([[0, -u0[2], u0[1]], [u0[2], 0, -u0[0]], [-u0[1], u0[0], 0]])
    r = np.zeros((len(s), 3))
    for i, si in enumerate(s):
        if a * si < 1e-4:  # series of (1 - cos)/a^2 and (a s - sin)/a^3 (no 0/0)
            c1 = si**2 / 2 - a**2 * si**4 / 24
            c2 = si**3 / 6 - a**2 * si**5 / 120
        else:
            c1 = (1 - np.cos(a * si)) / a**2
            c2 = (a * si - np.sin(a * si)) / a**3
        r[i] = (si * np.eye(3) + c1 * U + c2 * U @ U) @ v0
    q = np_quaternion_from_rotation_vector(np.outer(s, u0))
    return r, q


def stress_free(model, s) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) at parameter values s: each rod's helix of its reference strains, turned by
    its orientation and moved to its position (rods.Rod; layout.py for s)."""
    s = np.asarray(s, float)
    if model.layout.single and not model.rods[0].placed:
        p = model.params
        return helix(s, p.reference_curvature, p.reference_stretch)
    r, q = np.zeros((len(s), 3)), np.zeros((len(s), 4))
    rod_of = model.layout.rod_of(s)
    for k, rod in enumerate(model.rods):
        on = rod_of == k
        r[on], q[on] = placed_shape(rod, s[on] - model.layout.starts[k])
    return r, q


def placed_shape(rod, s) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) of one rod (rods.Rod) at its own arc lengths s: the helix of its reference
    strains, turned by its orientation, moved to its position."""
    r, q = helix(s, rod.params.reference_curvature, rod.params.reference_stretch)
    turn = np_quaternion_from_rotation_vector(np.asarray(rod.orientation, float))
    return (np.asarray(rod.position, float) + r @ np_rotation_matrix(turn).T,
            np_qmul(turn, q))


def set_initial_state(model, natural_curvature=None, natural_stretch=None) -> None:
    """See RodModel.set_initial_state."""
    unk = model.unknowns
    f = unk.f
    for g in [*f.values(), *unk.r.values(), *unk.acc.values()]:
        g.x.array[:] = 0.0
    f["displacement"].interpolate(
        lambda X: (stress_free(model, X[0])[0] - np.outer(X[0], [0, 0, 1.0])).T)
    if unk.chart is not None:
        unk.chart.set_nodal_rotations(lambda s: stress_free(model, s)[1])
    else:
        f["quaternion"].interpolate(lambda X: stress_free(model, X[0])[1].T)
    for supports in model.end_supports:
        supports.committed_time = None
        for end in ENDS:
            e_s = supports.s_ends[end]
            r, qq = stress_free(model, np.array([e_s]))
            supports.initial[end] = (r[0] - np.array([0, 0, e_s]), qq[0])
    for g in f.values():
        g.x.scatter_forward()
    u_ref, v_ref = model.reference
    pts = compat.interpolation_points(u_ref.function_space)
    u_ref.interpolate(fem.Expression(model.u, pts))
    v_ref.interpolate(fem.Expression(model.v, pts))
    if model.evolving:
        # natural strains: given constants, else the discrete strains (local variant) or
        # their mean (uniform variant): unstressed at t = 0 (issue 13 item 18: the
        # continuum u0 left an O(h^2) stress in the uniform variant)
        _fill_natural(model, "natural_curvature", natural_curvature, u_ref)
        if "natural_stretch" in f:
            _fill_natural(model, "natural_stretch", natural_stretch, v_ref)
        for g in f.values():
            g.x.scatter_forward()
    model.set_supports(0.0)


def _means(model, field) -> np.ndarray:
    """(1/L_k) int_rod k field ds of a DG0 vector field, one row per rod (MPI-reduced)."""
    chi = model.pieces.indicator
    parts = [fem.assemble_scalar(fem.form(chi(k) * field[i] * ufl.dx(domain=model.mesh)))
             for k in range(len(model.rods)) for i in range(3)]
    total = np.array(model.mesh.comm.allreduce(np.array(parts), op=MPI.SUM)).reshape(-1, 3)
    return total / np.array(model.layout.lengths)[:, None]


def _fill_natural(model, name, given, discrete) -> None:
    g = model.unknowns.f[name]
    if given is not None:
        val = np.broadcast_to(np.asarray(given, float), (g.x.array.size // 3 or 1, 3))
    elif model.variant == "local":
        val = discrete.x.array.reshape(-1, 3)
    else:     # one global value: the mean of the discrete strains, so no initial stress
        val = _means(model, discrete)
    if model.constraint == "unshearable" and name == "natural_stretch":
        g.x.array[:] = np.broadcast_to(val[:, 2], g.x.array.shape)
    else:
        g.x.array[:] = np.broadcast_to(val, (g.x.array.size // 3, 3)).ravel()
