"""The rod's initial state: the stress-free configuration of the reference strains (a
straight rod along e_3, or the helix/circle of constant reference_curvature, or the
curve ``reference_shape``: a polyline with kinks, an arc, ...) gives the
reference strains and the natural strains (the discrete reference strains, uniform
variant: their mean, unless given); the rod starts at rest there, or in a starting
state (rod/start.py: placed, another centre line, velocities, static equilibrium)."""

from __future__ import annotations

from dataclasses import replace

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from ..fem import compat, form_cache
from ..fem.fe_model import ENDS
from ..fem.solvers import BlockSNES, SolverError
from ..theory.rotations import np_qmul
from .placement import placed_shape, shape

E3 = np.array([0.0, 0.0, 1.0])


def stress_free(model, s) -> tuple[np.ndarray, np.ndarray]:
    """(r, q) at parameter values s: each rod's helix of its reference strains, turned by
    its orientation and moved to its position (rods.Rod; layout.py for s)."""
    s = np.asarray(s, float)
    if model.layout.single and not model.rods[0].placed:
        return shape(model.params, s, model.layout.n_cells[0])
    r, q = np.zeros((len(s), 3)), np.zeros((len(s), 4))
    rod_of = model.layout.rod_of(s)
    for k, rod in enumerate(model.rods):
        on = rod_of == k
        r[on], q[on] = placed_shape(rod, s[on] - model.layout.starts[k])
    return r, q


def set_initial_state(model, natural_curvature=None, natural_stretch=None,
                      start=None) -> None:
    """See RodModel.set_initial_state; ``start`` a rod.start.StartingState or None."""
    unk = model.unknowns
    f = unk.f
    for g in [*f.values(), *unk.r.values(), *unk.acc.values()]:
        g.x.array[:] = 0.0
    _set_configuration(model, lambda s: stress_free(model, s))
    for g in f.values():
        g.x.scatter_forward()
    _set_reference_strains(model)
    u_ref, v_ref = model.reference
    if model.evolving:
        # natural strains: given constants, else the discrete strains (local variant) or
        # their mean (uniform variant): unstressed at t = 0 (issue 13 item 18: the
        # continuum u0 left an O(h^2) stress in the uniform variant)
        _fill_natural(model, "natural_curvature", natural_curvature, u_ref)
        if "natural_stretch" in f:
            _fill_natural(model, "natural_stretch", natural_stretch, v_ref)
        for g in f.values():
            g.x.scatter_forward()
    if start is not None:   # the starting state moves the rod off its stress-free shape
        _set_configuration(model, lambda s: start.frames(
            s, lambda x: stress_free(model, x), model.length, model.layout.n_cells[0]))
        _set_velocities(model, start)
        for g in [*f.values(), *unk.r.values()]:
            g.x.scatter_forward()
    model.set_supports(0.0)
    if start is not None and start.equilibrium:
        settle(model, 0.0)


def hold_ends(model) -> None:
    """Each end's initial (x, q), which its support holds and its prescribed motions and
    springs start from, where the fields have it now (a run starting from a saved state,
    output/from_run.py), and the supports' values at t = 0 from there.  Collective."""
    from .diagnostics import Tip
    for supports in model.end_supports:
        supports.committed_time = None
        for end in ENDS:
            s = supports.s_ends[end]
            tip = Tip(model.unknowns, s)()
            x = np.array([tip[f"tip_position_{c}"] for c in "xyz"]) - np.array([0, 0, s])
            supports.initial[end] = (x, np.array([tip[f"tip_quaternion_{i}"]
                                                  for i in range(4)]))
    model.set_supports(0.0)


def _set_reference_strains(model) -> None:
    """u_ref, v_ref: the discrete strains of the stress-free configuration at the cell
    midpoints.  A single straight rod along e_3 (no placement) has q = (1, 0, 0, 0) and
    x = 0 at every node, for which the strain kernels give u = 0 and v = e_3 exactly
    (tests/test_setup_speed.py): written directly, without compiling an expression."""
    u_ref, v_ref = model.reference
    rod = model.rods[0]
    if model.layout.single and not rod.placed and is_straight(rod.params):
        u_ref.x.array[:] = 0.0
        v_ref.x.array.reshape(-1, 3)[:] = E3
        return
    pts = compat.interpolation_points(u_ref.function_space)
    u_ref.interpolate(fem.Expression(model.u, pts))
    v_ref.interpolate(fem.Expression(model.v, pts))


def is_straight(params) -> bool:
    """Reference strains u = 0, v = e_3: the stress-free rod is straight along e_3."""
    return (np.array_equal(np.asarray(params.reference_curvature, float), np.zeros(3))
            and np.array_equal(np.asarray(params.reference_stretch, float), E3)
            and params.reference_shape is None)


def _set_configuration(model, frames) -> None:
    """Displacement x = r - s e3, the nodal rotations and the ends' initial (x, q) of the
    configuration ``frames(s) -> (r, q)`` (nodal values at the parameter values s)."""
    unk = model.unknowns
    unk.f["displacement"].interpolate(
        lambda X: (frames(X[0])[0] - np.outer(X[0], [0, 0, 1.0])).T)
    if unk.chart is not None:
        unk.chart.set_nodal_rotations(lambda s: frames(s)[1])
    else:
        unk.f["quaternion"].interpolate(lambda X: frames(X[0])[1].T)
    for supports in model.end_supports:
        supports.committed_time = None
        for end in ENDS:
            e_s = supports.s_ends[end]
            r, qq = frames(np.array([e_s]))
            supports.initial[end] = (r[0] - np.array([0, 0, e_s]), qq[0])


def _set_velocities(model, start) -> None:
    """The starting velocities at the nodes: V and the material angular velocity
    W = R^T w (rotation vectors: the rates of the displacement and the rotation
    increment, which the integrator reads; quaternions: the velocity fields and the
    rates x_t = V, q_t = q (0, W)/2 consistent with them), zero at held ends."""
    unk = model.unknowns
    if not start.moving:
        return
    x = unk.f["displacement"]
    s = x.function_space.tabulate_dof_coordinates()[:, 0]
    q = (unk.chart.q_n if unk.chart is not None else unk.f["quaternion"]).x.array.reshape(-1, 4)
    v, w = start.velocities(s, x.x.array.reshape(-1, 3) + np.outer(s, [0, 0, 1.0]))
    conj = q * np.array([1.0, -1, -1, -1])
    W = np_qmul(np_qmul(conj, np.hstack([np.zeros((len(s), 1)), w])), q)[:, 1:] \
        / np.einsum("ij,ij->i", q, q)[:, None]
    for supports in model.end_supports:
        for end in ENDS:
            at_end = np.isclose(s, supports.s_ends[end])
            if (unk.rotation, end) in supports.values:
                W[at_end] = 0.0
            if ("displacement", end) in supports.values:
                v[at_end] = 0.0
    if unk.chart is not None:
        unk.r["displacement"].x.array[:] = v.ravel()
        unk.r["rotation_increment"].x.array[:] = W.ravel()
        return
    unk.f["velocity"].x.array[:] = v.ravel()
    unk.f["angular_velocity"].x.array[:] = W.ravel()
    unk.r["displacement"].x.array[:] = v.ravel()
    unk.r["quaternion"].x.array[:] = 0.5 * np_qmul(
        q, np.hstack([np.zeros((len(s), 1)), W])).ravel()


BALANCE = ("displacement", "quaternion", "rotation_increment", "gauge_multiplier",
           "constraint_multiplier")


def settle(model, t: float) -> None:
    """Static equilibrium of the positions and rotations (the blocks of BALANCE; natural
    strains fixed) with the loads and supports at t, from the current state, rates and
    accelerations held at zero meanwhile; rotation vectors: committed to the stored
    rotations.  ValueError if Newton finds none."""
    unk, problem = model.unknowns, model.problem
    names = [n for n in model.names if n in BALANCE]
    moving = [g for g in [*unk.r.values(), *unk.acc.values()] + [
        unk.f[n] for n in ("velocity", "angular_velocity") if n in unk.f]]
    saved = [g.x.array.copy() for g in moving]
    for g in moving:
        g.x.array[:] = 0.0
    problem.set_loads(t)
    problem.set_bcs(t)
    links = [replace(link, block=names.index(model.names[link.block]))    # joints
             for link in problem.links]
    solver = BlockSNES([model.residual[n] for n in names], [unk.f[n] for n in names],
                       [bc for n in names for bc in model.bcs_of(n)],
                       {"snes_max_it": 50}, step_scale=problem.configuration_norm(),
                       links=links, terms=problem.terms,      # segment contact's pairs
                       force_scale=problem.force_scale, static=True)
    try:
        solver.solve()
    except SolverError as err:
        raise ValueError(f"start.equilibrium: no static equilibrium found from the starting "
                         f"shape at t = {t:g} ({err}); is the rod supported against rigid "
                         "motions?") from err
    finally:
        for g, array in zip(moving, saved):
            g.x.array[:] = array
    if unk.chart is not None:
        model.commit_rotations()


def _means(model, field) -> np.ndarray:
    """(1/L_k) int_rod k field ds of a DG0 vector field, one row per rod (MPI-reduced)."""
    chi = model.pieces.indicator
    dx = ufl.dx(domain=model.mesh)
    parts = [fem.assemble_scalar(form_cache.jit_form(chi(k) * field[i] * dx))
             for k in range(len(model.rods)) for i in range(3)]
    total = np.array(model.mesh.comm.allreduce(np.array(parts), op=MPI.SUM)).reshape(-1, 3)
    return total / np.array(model.layout.lengths)[:, None]


def check_natural(name: str, given, rod_names: list[str]) -> None:
    """A given natural strain: None, a finite 3-vector, or {rod name: finite 3-vector}
    (ValueError naming ``name`` and the rod)."""
    if given is None:
        return
    for rod_name, value in (given.items() if isinstance(given, dict) else [(None, given)]):
        where = name if rod_name is None else f"{name}[{rod_name!r}]"
        if rod_name is not None and rod_name not in rod_names:
            raise ValueError(f"{where}: no rod of that name (rods: {rod_names})")
        value = np.asarray(value, float)
        if value.shape != (3,) or not np.all(np.isfinite(value)):
            raise ValueError(f"{where} must be a finite 3-vector, got {value.tolist()}")


def _fill_natural(model, name, given, discrete) -> None:
    """The natural strain block ``name``: each rod's given 3-vector (``given``: one for
    every rod, or {rod name: 3-vector} for some), else its discrete reference strains
    (local variant) or their mean (uniform: one global value per rod, so no initial
    stress)."""
    g = model.unknowns.f[name]
    names = [rod.name for rod in model.rods]
    per_rod = given if isinstance(given, dict) else dict.fromkeys(
        names if given is not None else (), given)
    if model.variant == "local":
        val = discrete.x.array.reshape(-1, 3).copy()
        rod_of = model.layout.rod_of(discrete.function_space.tabulate_dof_coordinates()[:, 0])
    else:
        val = _means(model, discrete)
        rod_of = np.arange(len(names))
    for rod_name, value in per_rod.items():
        val[rod_of == names.index(rod_name)] = np.asarray(value, float)
    if model.constraint == "unshearable" and name == "natural_stretch":
        g.x.array[:] = np.broadcast_to(val[:, 2], g.x.array.shape)
    else:
        g.x.array[:] = np.broadcast_to(val, (g.x.array.size // 3, 3)).ravel()
