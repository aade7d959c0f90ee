"""The rod's initial state: the stress-free configuration of the reference strains (a
straight rod along e_3, or the helix/circle of constant reference_curvature, or the
curve ``reference_shape``: a polyline with kinks, an arc, ...) gives the
reference strains and the natural strains (the discrete reference strains, uniform
variant: their mean, unless given); the rod starts at rest there, or in a starting
state (rod/start.py: placed, another centre line, velocities, static equilibrium)."""

from __future__ import annotations

import math
from dataclasses import replace

import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from ..fem import compat, form_cache
from ..fem.fe_model import ENDS
from ..fem.solvers import BlockSNES, SolverError
from ..mpi import largest_on_ranks
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
    model.problem.start_loaded = False      # given, unloaded (settle: in equilibrium)
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
# A settle that one Newton solve does not reach (_settle_in_pseudo_time)
SETTLE_STEPS = 200        # pseudo-time steps at most
TETHER_RELEASE = 8.0      # the tether's stiffness divided by this after an accepted step
TETHER_HOLD = 4.0         # ... multiplied by this after a failed one
SETTLE_FAILURES = 12      # failed steps in a row before the settle gives up
SETTLE_TRAVEL = 100.0     # ... or when a node moved by this many rod lengths
NO_SETTLE = "start.equilibrium: no static equilibrium found"
TETHER_FLOOR = 1e-12      # unconverged with the tether released below this share of its
                          # first stiffness: the loads move the rod without bound


def settle(model, t: float) -> None:
    """Static equilibrium of the positions and rotations (the blocks of BALANCE; natural
    strains fixed) with the loads and supports at t, from the current state, rates and
    accelerations held at zero meanwhile; rotation vectors: committed to the stored
    rotations.  First one Newton solve from the current state (a rod an end holds; with
    contact, its state checked: no node inside an obstacle); where that fails, or no end
    holds the rod's rotation, in pseudo-time (_settle_in_pseudo_time: a large deflection,
    a rod resting on obstacles, a pinned or jointed rod whose spin nothing holds).
    ValueError (start.equilibrium) if none is found."""
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
    fields = [unk.f[n] for n in names]
    law = (model.contact.law if model.contact else
           model.segment_terms[0].law if model.segment_terms else None)
    bcs = [bc for n in names for bc in model.bcs_of(n)]

    def solver(*terms):
        return BlockSNES([model.residual[n] for n in names], fields, bcs, {"snes_max_it": 50},
                         step_scale=problem.configuration_norm(), links=links,
                         terms=[*problem.terms, *terms], force_scale=problem.force_scale,
                         static=True)

    given = [f.x.array.copy() for f in fields]
    try:
        try:
            if not rotation_held(model):    # (resting on an obstacle: singular at first)
                raise SolverError("no end holds the rod", 0)
            one = solver()
            one.solve()
            reason = problem.check_step()
            if reason:
                raise SolverError(reason, one.iterations)
        except SolverError:
            for f, array in zip(fields, given):
                f.x.array[:] = array
            # a solver of its own (MUMPS, 2 ranks: a factorisation failed in the one
            # solve failed the next solves of its solver); the tether's reach: a barrier's
            # gap with contact (a node comes to rest within it), else a cell (a step of
            # the large deflection the one solve missed)
            h = model.length / sum(model.layout.n_cells)
            tether = Tether([(unk.f["displacement"], 1.0), (unk.f[unk.rotation], h * h)])
            keeper = model.contact.gap_keeping() if model.contact else None
            _settle_in_pseudo_time(model, solver(*(term for term in (tether, keeper) if term)),
                                   tether, keeper, fields, law.gap if law is not None else h, t)
    except SolverError as err:
        raise ValueError(f"{NO_SETTLE} from the starting shape at t = {t:g} ({err}): Newton "
                         "did not reach it under the whole load at once (a large "
                         "deflection); start nearer to it (initial.shape), or let the rod "
                         "settle in time without equilibrium (with material.drag)") from err
    finally:
        for g, array in zip(moving, saved):
            g.x.array[:] = array
    if unk.chart is not None:
        model.commit_rotations()
    problem.start_loaded = True


def supported(model) -> bool:
    """Whether something holds the rod against rigid motions, as a static equilibrium
    needs: an end support (clamped, pinned, a prescribed motion, a spring) or obstacles
    to rest on (rod/start.py check_start's ``supported``)."""
    return model.contact is not None or any(
        bool(supports.values) or bool(supports.springs) for supports in model.end_supports)


def rotation_held(model) -> bool:
    """Whether an end of a rod holds its rotation (clamped, or a prescribed rotation)."""
    return any("clamped" in supports.ends or bool(supports.rotation)
               for supports in model.end_supports)


def _settle_in_pseudo_time(model, solver, tether, keeper, fields, reach: float,
                           t: float) -> None:
    """The static equilibrium by pseudo-time continuation: each step solves
    R(y) + k W (y - y_0) = 0 from the last accepted state y_0 (Tether: a spring of
    stiffness k per node tying each node to where it was, W weighting the rotations by
    the cell length squared: a proximal-point step, which descends to a stable
    equilibrium), its Newton updates shortened so that no node comes near an obstacle
    faster than its gap allows (ObstacleContact.gap_keeping; segment pairs and segment
    obstacles limit theirs always); an accepted step (converged, checked:
    problem.check_step, e.g. a rotation increment below a quarter turn) is committed and
    k released by TETHER_RELEASE, a failed one is undone and k raised by TETHER_HOLD.
    The rod so travels to an obstacle it has to reach, the barrier taking over
    gradually, or bends through a large deflection in committed parts, and the tether,
    whose force is the rest of the residual, k |W (y - y_0)|, fades; converged when that
    is below Newton's absolute tolerance.  The tether also holds what nothing else holds
    (a free rod lying on a frictionless floor: sliding along it, turning about its axis;
    a pinned rod's spin), where it is never stretched.  k starts at S / (nodes reach):
    the force scale S (force_scale.py) moves a node by about ``reach`` (a barrier's gap,
    or a cell).  ValueError (start.equilibrium) when SETTLE_FAILURES steps in a row fail,
    or when it has not converged as k falls below TETHER_FLOOR of its start, a node has
    moved by SETTLE_TRAVEL rod lengths or SETTLE_STEPS are done (a rod nothing holds
    against its loads keeps moving: friction has no force at rest)."""
    problem = model.problem
    nodes = fields[0].function_space.dofmap.index_map.size_global
    tether.stiffness = first = problem.force_scale() / (nodes * reach)
    if keeper is not None:
        keeper.active = True
    problem.after_step()            # the contacts' path checks start here
    failures, reason, force, travel = 0, "", math.inf, 0.0
    x = model.unknowns.f["displacement"]
    given = x.x.array.copy()
    try:
        for _ in range(SETTLE_STEPS):
            start = [f.x.array.copy() for f in fields]
            tether.restart()
            try:
                solver.solve()
                reason = problem.check_step()
            except SolverError as err:
                reason = str(err)
            if reason:
                for f, array in zip(fields, start):
                    f.x.array[:] = array
                failures += 1
                if failures > SETTLE_FAILURES:
                    where = model.where_failed()
                    raise ValueError(f"{NO_SETTLE} at t = {t:g}: {failures} pseudo-time "
                                     f"steps in a row failed, the last: {reason}"
                                     + (f" ({where})" if where else ""))
                tether.stiffness *= TETHER_HOLD
                continue
            failures, force = 0, tether.force()
            problem.after_step()
            if force <= solver.snes.getTolerances()[1]:
                return
            travel = largest_on_ranks(problem.comm, float(np.max(np.linalg.norm(
                (x.x.array - given).reshape(-1, 3), axis=1), initial=0.0)))
            if tether.stiffness < TETHER_FLOOR * first or travel > SETTLE_TRAVEL * model.length:
                break
            tether.stiffness /= TETHER_RELEASE
    finally:
        tether.stiffness = 0.0
        if keeper is not None:
            keeper.active = False
    raise ValueError(f"{NO_SETTLE} at t = {t:g}: the loads still move the rod (unbalanced "
                     f"force {force:.3g} after it moved by up to {travel:.3g}): nothing holds it "
                     "against them (friction has no force in a static settle: a rod on a "
                     "slope slides off)")


class Tether:
    """The pseudo-time term of a settle (fem/assembly add_terms): k w (y - y_0)
    on the owned rows of the ``fields`` [(Function, weight w)], y_0 the state at the
    first residual after ``restart`` (a solve's start); k = ``stiffness`` (0: no term,
    bit for bit)."""

    def __init__(self, fields: list):
        self.fields, self.stiffness, self.bound = fields, 0.0, []

    def bind(self, system) -> "_BoundTether":
        bound = _BoundTether(self, system)
        self.bound.append(bound)
        return bound

    def restart(self) -> None:
        for bound in self.bound:
            bound.anchor = None

    def force(self) -> float:
        """|k w (y - y_0)| at the last residual, over all ranks."""
        local = sum(bound.squared for bound in self.bound)
        comm = self.fields[0][0].function_space.mesh.comm
        return math.sqrt(comm.allreduce(local, op=MPI.SUM))


class _BoundTether:
    def __init__(self, tether: Tether, system):
        rows, weights = [], []
        for k, y in enumerate(system.groups[0]):
            for f, w in tether.fields:
                if y is f:
                    index_map = f.function_space.dofmap.index_map
                    n = index_map.size_local * f.function_space.dofmap.index_map_bs
                    rows.append(system.rows_of(k, np.arange(n)))
                    weights.append(np.full(n, w))
        self.tether, self.rows = tether, np.concatenate(rows).astype(np.intp)
        self.weights = np.concatenate(weights)
        first = system.x.getOwnershipRange()[0]
        self.global_rows = (self.rows + first).astype(PETSc.IntType).reshape(-1, 1)
        self.anchor, self.squared = None, 0.0

    def add_residual(self, x_owned: np.ndarray, b_owned: np.ndarray) -> None:
        y = x_owned[self.rows]
        if self.anchor is None:
            self.anchor = y.copy()
        force = self.tether.stiffness * self.weights * (y - self.anchor)
        b_owned[self.rows] += force
        self.squared = float(force @ force)

    def missing_entries(self):
        return None         # the diagonal is in every block's pattern

    def add_jacobian(self, A) -> None:
        A.setValuesRCV(self.global_rows, self.global_rows,
                       (self.tether.stiffness * self.weights).reshape(-1, 1, 1),
                       addv=PETSc.InsertMode.ADD_VALUES)


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
