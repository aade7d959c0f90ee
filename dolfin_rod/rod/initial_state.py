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
from ..theory.rotations import np_quaternion_from_rotation_vector
from ..fem.fe_model import ENDS, end_coordinate


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


def set_initial_state(model, natural_curvature=None, natural_stretch=None) -> None:
    """See RodModel.set_initial_state."""
    unk = model.unknowns
    f = unk.f
    for g in [*f.values(), *unk.r.values(), *unk.acc.values()]:
        g.x.array[:] = 0.0
    u0 = np.asarray(model.params.reference_curvature, float)
    v0 = np.asarray(model.params.reference_stretch, float)
    f["displacement"].interpolate(
        lambda X: (helix(X[0], u0, v0)[0] - np.outer(X[0], [0, 0, 1.0])).T)
    if unk.chart is not None:
        unk.chart.set_nodal_rotations(lambda s: helix(s, u0, v0)[1])
        model.supports.committed_time = None
    else:
        f["quaternion"].interpolate(lambda X: helix(X[0], u0, v0)[1].T)
    for end in ENDS:
        e_s = end_coordinate(end, model.length)
        r, qq = helix(np.array([e_s]), u0, v0)
        model.supports.initial[end] = (r[0] - np.array([0, 0, e_s]), qq[0])
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
    model.supports.set(0.0)


def _mean(model, field) -> np.ndarray:
    """(1/L) int field ds of a DG0 vector field (MPI-reduced)."""
    parts = [fem.assemble_scalar(fem.form(field[i] * ufl.dx(domain=model.mesh)))
             for i in range(3)]
    return np.array(model.mesh.comm.allreduce(np.array(parts), op=MPI.SUM)) / model.length


def _fill_natural(model, name, given, discrete) -> None:
    g = model.unknowns.f[name]
    if given is not None:
        val = np.broadcast_to(np.asarray(given, float), (g.x.array.size // 3 or 1, 3))
    elif model.variant == "local":
        val = discrete.x.array.reshape(-1, 3)
    else:     # one global value: the mean of the discrete strains, so no initial stress
        val = np.atleast_2d(_mean(model, discrete))
    if model.constraint == "unshearable" and name == "natural_stretch":
        g.x.array[:] = np.broadcast_to(val[:, 2], g.x.array.shape)
    else:
        g.x.array[:] = np.broadcast_to(val, (g.x.array.size // 3, 3)).ravel()
