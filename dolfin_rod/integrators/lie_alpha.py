"""Generalized-alpha for second-order forms on a Lie group (Arnold & Bruls 2007,
Chung & Hulbert 1993), positions and rotation increments as the only unknowns.

A SecondOrderProblem with ``time_orders`` (2: the block's rates and accelerations enter;
1: only its rates) is advanced by one residual in y_{n+1}.  Per second-order block,
with d = y_{n+1} - y_n (for a rotation increment y_n = 0: d is the material increment
of the nodal rotations),

    d        = h v_n + h^2 ((1/2 - beta) a_n + beta a_{n+1})
    v_{n+1}  = v_n + h ((1 - gamma) a_n + gamma a_{n+1})
    (1 - alpha_m) a_{n+1} + alpha_m a_n = (1 - alpha_f) ydd_{n+1} + alpha_f ydd_n,

and the residual holds at t_{n+1} with (v_{n+1}, ydd_{n+1}); a first-order block has
d = h ((1 - gamma) b_n + gamma b_{n+1}) and the same filter between b and y'; an
algebraic block (time order 0: neither its rate nor its acceleration enters, e.g. the
positions and rotations of a quasi-static rod) is solved at t_{n+1}, and its rate after
the step is d/h (diagnostics, the predictor).  The start then solves the algebraic
blocks and the other blocks' rates together: the consistent initial state of the
index-1 DAE (a quasi-static rod in equilibrium with its loads at t0).
alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f - alpha_m,
beta = (gamma + 1/2)^2 / 4: second order, unconditionally stable, high-frequency
spectral radius rho_inf.  The start needs consistent accelerations (solved at t0).

Error control (``tolerance``): the local error of the positions and rotation increments
is estimated per step (LocalError) and the step sizes follow it (stepping.StepControl).
"""

from __future__ import annotations

import math

import dolfinx.fem as fem
import numpy as np
import ufl

from ..checks import MAX_STEP_CUTS
from ..fem import compat, form_cache
from ..fem.solvers import BlockSNES, SolverError
from ..mpi import largest_on_ranks
from .schemes import alpha_rho_inf
from .step_control import (CUT_FACTOR, IntegrationError, StepControl, StepStats, check_run,
                           load_path, march, nominal_steps, step_failure)


def default_options(comm, second_order: bool = True, direct: bool = False) -> dict:
    """The integrator's solver defaults.

    One rank: PETSc's own LU in the natural order (the banded order of a 1-D mesh; safe
    without pivoting: there is no saddle point).  Several ranks, quasi-static (no
    second-order block): MUMPS.  Several ranks, dynamic: GMRES preconditioned by
    that LU on each rank's diagonal block (block Jacobi): the preconditioned operator is
    the identity plus a rank <= 2 b (ranks - 1) coupling through the interface nodes, so
    GMRES converges in a few iterations (2.6x cheaper than MUMPS at 2e4 cells on 2 ranks,
    same tip to all digits, docs/performance.md); with terms outside the forms
    (``direct``: segment contact, whose pairs couple ranks far from the interface)
    MUMPS (block Jacobi's GMRES stalled Newton when a plectoneme's loop closed across
    the ranks).  Newton: rtol 1e-4 with a second-order
    block (the predictor's residual is O(dt^3) small already, so 1e-4 of it is far below
    the step's truncation error: the peer benchmark's tip errors are those of rtol 1e-6
    to 3 digits at every mesh, with 2.44 instead of 3.64 Newton iterations per step at
    8 cells, soft scene; at most checks.NEWTON_FORCE_CAP of the force scale, where the
    first residual is dominated by stiff rows: solvers.relative_tolerance), else
    BlockSNES's 1e-10 (a quasi-static step's first
    residual is the load increment); each step's Newton starts with a new Jacobian and
    LU and keeps them while every iteration reduces the residual 10-fold (BlockSNES's
    default, solvers.REUSE_RATIO): 1.0-1.5 Jacobians per step on the benchmark scenes
    instead of 1.9-2.6 with a refresh every second iteration, fewer step cuts
    (docs/performance.md).
    """
    options = {"snes_rtol": 1e-4} if second_order else {}
    if comm.size == 1:
        options.update(pc_factor_mat_solver_type="petsc", pc_factor_mat_ordering_type="natural")
    elif not second_order or direct:
        # a stiffness matrix alone (no mass to keep it well conditioned): MUMPS, whose
        # direct solve holds where GMRES cannot reduce a residual at its round-off floor
        # (E A / E I ~ 1e8: DIVERGED_LINEAR_SOLVE, tests/test_rod.py's locking test)
        options.update(pc_factor_mat_solver_type="mumps")
    else:
        # right preconditioning: ksp_atol applies to the true residual (left: to the
        # preconditioned one, ~ beta h^2 / rho_A of it, below 1e-14 at small steps, where
        # GMRES then stopped after 0 iterations and Newton stalled: dt = 1e-4, 4 cells)
        options.update(ksp_type="gmres", ksp_rtol=1e-12, ksp_atol=1e-14, ksp_pc_side="right",
                       pc_type="bjacobi", sub_pc_type="lu",
                       sub_pc_factor_mat_ordering_type="natural")
    return options


def solver_settings(comm, solver_options: dict | None, second_order: bool = True,
                    direct: bool = False) -> dict:
    """default_options updated by ``solver_options``."""
    return {**default_options(comm, second_order, direct), **(solver_options or {})}


def alpha_parameters(rho_inf: float):
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) ** 2
    return am, af, gamma, beta


class StepRejected(SolverError):
    """The step's local error estimate exceeds the tolerance (state restored)."""

    def __init__(self, error: float):
        RuntimeError.__init__(self, f"local error {error:.3g} x tolerance")
        self.reason, self.iterations, self.error = "local error above tolerance", 0, error


def error_coefficient(gamma: float, beta: float) -> float:
    """c of the local position error h^2 c (a_{n+1} - a_n) of generalized-alpha.

    Zienkiewicz & Xie (1991, Earthquake Eng. Struct. Dyn. 20:871) estimate Newmark's
    local displacement error as h^2 (beta - 1/6)(a_{n+1} - a_n): a Taylor expansion of
    d = h v_n + h^2 ((1/2 - beta) a_n + beta a_{n+1}) with a_n = y''(t_n) leaves
    h^3 y'''(t_n) (beta - 1/6), and h y''' = a_{n+1} - a_n + O(h^2).  In
    generalized-alpha the algorithmic acceleration approximates the acceleration at a
    shifted time, a_n = y''(t_n + delta h) + O(h^2), delta = alpha_m - alpha_f =
    1/2 - gamma (Arnold & Bruls 2007, Multibody Syst. Dyn. 18:185, sec. 3).  Then
    d = h v_n + h^2/2 y'' + h^3 y''' (beta + delta/2) + O(h^4) against the exact
    h v_n + h^2/2 y'' + h^3/6 y''': the local error is h^3 y''' (beta + delta/2 - 1/6)
    = h^2 (beta - gamma/2 + 1/12)(a_{n+1} - a_n).  Newmark (gamma = 1/2) gives back
    beta - 1/6; rho_inf = 0.8 gives 0.086."""
    return abs(beta - gamma / 2 + 1.0 / 12.0)


class LocalError:
    """The weighted local error of a step (<= 1: within the tolerance).

    Per second-order block (displacements, rotation increments; the first-order blocks,
    e.g. natural strains, follow the controlled strains and are not controlled
    themselves) e = error_coefficient h^2 (a_{n+1} - a_n), weighted by
        w = atol * scale + rtol * max(|y_n|, |y_{n+1}|),
    ``scale`` the problem's ``error_scales`` (the rod: its length for a displacement, 1
    rad for a rotation increment, whose value is the step's increment, so atol rules it;
    else the mesh's extent).  The norm is max |e_i| / w_i over each rank's owned dofs, reduced by MPI
    MAX: the same on every rank and for every partition.  Prescribed (Dirichlet) dofs are
    included: their a is that of the prescribed motion, smooth in time."""

    def __init__(self, integrator, control: StepControl):
        self.ig, self.control = integrator, control
        self.c = error_coefficient(integrator.gamma, integrator.beta)
        self.comm = integrator.problem.comm
        fields = integrator.problem.fields
        scales = integrator.problem.block_scales()
        self.blocks = []
        for i, (f, scale) in enumerate(zip(fields, scales)):
            if integrator.order[i] == 2:
                dofmap = f.function_space.dofmap
                owned = dofmap.index_map.size_local * dofmap.index_map_bs
                self.blocks.append((i, owned, scale))
        if not self.blocks:
            raise ValueError("tolerance: the error estimate needs a second-order block "
                             "(time_orders 2: the displacements and rotations of a dynamic "
                             "rod); this problem has none (a quasi-static rod: fixed steps)")

    def __call__(self, h: float, arrays: list) -> float:
        """The weighted error of the solved step, from the integrator's block arrays
        (step(): y solved, the history still at t_n)."""
        ctl, worst = self.control, 0.0
        for i, owned, scale in self.blocks:
            y, _, y_n, _, alg, _, _ = arrays[i]
            a_new = self.ig._np_update(i, y - y_n, h)[0]
            e = self.c * h * h * np.abs(a_new[:owned] - alg[:owned])
            w = ctl.atol * scale + ctl.rtol * np.maximum(np.abs(y[:owned]),
                                                         np.abs(y_n[:owned]))
            if owned:
                worst = max(worst, float(np.max(e / w)))
        return largest_on_ranks(self.comm, worst)


def _finite(y: np.ndarray) -> bool:
    """Whether every entry of y is finite: y . y is (one BLAS call, 3x cheaper than
    np.isfinite at a few nodes), unless an entry is not or the sum overflows (then the
    entries are checked)."""
    return math.isfinite(y @ y) or bool(np.isfinite(y).all())


def _copy(f, tag):
    g = fem.Function(f.function_space, name=f"{f.name}_{tag}")
    g.x.array[:] = f.x.array
    return g


EQUILIBRIUM_SUB_SOLVES = 4     # the consistent start's path to displaced ends: at least
START_PART_TURN = 0.5          # ... so many parts, and one per half radian of the largest turn


def start_parts(turn: float) -> int:
    """The parts of the consistent start's path to ends turned by ``turn`` (rad) at t0:
    EQUILIBRIUM_SUB_SOLVES, or one per START_PART_TURN radian if more, so that each part
    turns a node by well under the quarter turn that bounds one rotation increment
    (rotation_vector.check_increment) at any angle (a clamp turned by 20 rad: 40 parts;
    1 rad parts failed to converge for a frame of two jointed rods turned rigidly)."""
    return max(EQUILIBRIUM_SUB_SOLVES, math.ceil(turn / START_PART_TURN))


class LieGeneralizedAlpha:
    """Advance a second-order problem; ``problem.after_step`` moves the rotation
    increments into the stored rotations (and resets them to 0).  The interface of
    SchemeStepper (run, step, stats, checkpoint_state); integrators/choice.py picks this
    integrator for a SecondOrderProblem.

    ``tolerance`` None: fixed steps (run's dt).  A number tol in (0, 1): error-controlled
    steps, rtol = atol = tol in LocalError's norm (displacements to tol (L + |x|),
    rotation increments to tol rad per step); a StepControl for other rtol/atol or
    controller constants.  The global error then scales as tol^(2/3) (h ~ tol^(1/3),
    error ~ h^2; tests/test_adaptive.py)."""

    def __init__(self, problem, rho_inf: float = 0.8, solver_options=None, max_cuts: int = MAX_STEP_CUTS,
                 tolerance: float | StepControl | None = None):
        self.control = (tolerance if isinstance(tolerance, StepControl) or tolerance is None
                        else StepControl(tolerance, tolerance))
        self.problem = problem
        self.rho_inf, self.max_cuts = rho_inf, max_cuts
        self.am, self.af, self.gamma, self.beta = alpha_parameters(rho_inf)
        mesh = problem.fields[0].function_space.mesh
        self.dt = fem.Constant(mesh, 1.0)
        self.order = problem.time_orders or [2] * len(problem.fields)
        y, r, acc = problem.fields, problem.rates, problem.accelerations
        self.y_n = [_copy(f, "n") for f in y]
        self.v_n = [_copy(f, "rate_n") for f in r]
        self.acc_n = [None if a is None else _copy(a, "acc_n") for a in acc]
        # algorithmic accelerations a (second order) or rates b (first order)
        self.alg_n = [_copy(f, "alg_n") for f in r]
        # compiled step forms shared by all problems of this structure (form_cache)
        self._model_objects = form_cache.registry(problem.residual)
        self.structure_key = form_cache.structure_key(problem.residual, "lie_alpha", self.order,
                                                      rho_inf, structure=problem.structure)
        objects = [*self._model_objects, *self.y_n, *self.v_n,
                   *(a for a in self.acc_n if a is not None), *self.alg_n, self.dt]
        F = None if form_cache.lookup(self.structure_key, mesh.comm) else self._step_forms()
        self.options = options = solver_settings(mesh.comm, solver_options, 2 in self.order,
                                                 direct=bool(problem.terms))
        self.solver = BlockSNES(F, y, problem.bcs, options, cache=(self.structure_key, objects),
                                step_scale=problem.configuration_norm(),
                                links=problem.links, terms=problem.terms,
                                force_scale=problem.force_scale,
                                static=not problem.inertia)
        self._arrays = self._views()
        self._stacks = self._stacked_blocks()
        self._matrices = {}
        self.stats = StepStats()
        self._started = False
        self._dt_last = None
        self._initial_solver = None
        self.local_error = None if self.control is None else LocalError(self, self.control)
        self.last_error = 0.0     # weighted local error of the last solved step
        self.next_dt = None       # error control: the controller's next step
        self._rejections = 0      # error control: rejected steps in a row
        self._declared_rest = False   # the next step starts from accelerations set to 0

    @classmethod
    def for_scheme(cls, problem, scheme: str | None, solver_options=None, max_cuts: int = MAX_STEP_CUTS,
                   tolerance=None):
        """choose_integrator's arguments: ``scheme`` None (rho_inf 0.8) or 'generalized_alpha'
        ['RHO'] (schemes.alpha_rho_inf); a first-order scheme is refused."""
        if scheme is not None and not scheme.startswith("generalized_alpha"):
            raise ValueError(f"scheme {scheme!r}: a dynamic rod with rotation-vector unknowns "
                             "is advanced by generalized_alpha[:rho_inf] on the rotation "
                             "group only; for another scheme build RodModel(..., "
                             "rotations='quaternion')")
        rho_inf = 0.8 if scheme is None else alpha_rho_inf(scheme)
        return cls(problem, rho_inf, solver_options, max_cuts, tolerance)

    @property
    def description(self) -> str:
        text = f"generalized-alpha on the rotation group (rho_inf = {self.rho_inf:g})"
        if self.control is None:
            return text
        return f"{text}, adaptive steps (rtol = {self.control.rtol:g}, atol = " \
               f"{self.control.atol:g})"

    def _step_forms(self):
        p = self.problem
        mapping = {}
        for i, f in enumerate(p.fields):
            new_r, new_a = self._ufl_update(i, f - self.y_n[i])
            mapping[p.rates[i]] = new_r
            if p.accelerations[i] is not None:
                mapping[p.accelerations[i]] = new_a
        return [ufl.replace(Fi, mapping) for Fi in p.residual]

    def _ufl_update(self, i, d):
        """(rate, acceleration) at t_{n+1} as UFL expressions of the increment d."""
        h, am, af, g, b = self.dt, self.am, self.af, self.gamma, self.beta
        vn, alg = self.v_n[i], self.alg_n[i]
        if self.order[i] == 0:
            return d / h, None
        if self.order[i] == 2:
            a_new = (d - h * vn - h * h * (0.5 - b) * alg) / (h * h * b)
            v_new = vn + h * ((1 - g) * alg + g * a_new)
            acc_new = ((1 - am) * a_new + am * alg - af * self.acc_n[i]) / (1 - af)
            return v_new, acc_new
        b_new = (d - h * (1 - g) * alg) / (h * g)
        return ((1 - am) * b_new + am * alg - af * vn) / (1 - af), None

    def _np_update(self, i, d, h):
        """(algorithmic acceleration or rate, rate, acceleration) at t_{n+1} of block i
        from its increment d: _ufl_update's formulas as one matrix product (~3x fewer
        array operations per step; the columns stacked by np.array, 3x cheaper than
        np.vstack at a few nodes)."""
        if self.order[i] == 0:
            return d / h, d / h, None
        _, _, _, vn, alg, _, acc_n = self._arrays[i]
        C = self._update_matrix(self.order[i], h)
        out = C @ np.array((d, vn, alg) if self.order[i] == 1 else (d, vn, alg, acc_n))
        return out[0], out[1], out[2] if self.order[i] == 2 else None

    def _updates(self, h) -> list:
        """_np_update of every block at its step's increment y - y_n; the blocks of the
        same order and size (a rod's displacements and rotation increments) stacked in one
        matrix product (the same numbers: one product per block, one call)."""
        out = [None] * len(self._arrays)
        for order, blocks in self._stacks:
            if order == 0:
                for i in blocks:
                    y, _, y_n, *_ = self._arrays[i]
                    out[i] = self._np_update(i, y - y_n, h)
                continue
            columns = np.array([(y - y_n, vn, alg) if order == 1 else (y - y_n, vn, alg, acc_n)
                                for y, _, y_n, vn, alg, _, acc_n in
                                (self._arrays[i] for i in blocks)])
            rows = self._update_matrix(order, h) @ columns
            for i, row in zip(blocks, rows):
                out[i] = (row[0], row[1], row[2] if order == 2 else None)
        return out

    def _update_matrix(self, order: int, h: float) -> np.ndarray:
        """Rows (alg_new, rate_new[, acc_new]) as combinations of the columns
        (d, v_n, alg_n[, acc_n]) (_ufl_update); the last ones kept (h changes rarely)."""
        key = (order, h)
        if key not in self._matrices:
            am, af, g, b = self.am, self.af, self.gamma, self.beta
            if order == 2:
                a_new = np.array([1 / (h * h * b), -1 / (h * b), -(0.5 - b) / b, 0.0])
                v_new = np.array([0.0, 1.0, h * (1 - g), 0.0]) + h * g * a_new
                acc = ((1 - am) * a_new + np.array([0.0, 0.0, am, -af])) / (1 - af)
                rows = [a_new, v_new, acc]
            else:
                b_new = np.array([1 / (h * g), 0.0, -(1 - g) / g])
                rows = [b_new, ((1 - am) * b_new + np.array([0.0, -af, am])) / (1 - af)]
            if len(self._matrices) > 8:
                self._matrices.clear()
            self._matrices[key] = np.array(rows)
        return self._matrices[key]

    def _unknowns_at_start(self) -> list:
        """Per block what the start solves for: the acceleration (order 2), the rate
        (order 1) or the field itself (order 0, algebraic)."""
        p = self.problem
        return [f if k == 0 else a if a is not None else r
                for f, r, a, k in zip(p.fields, p.rates, p.accelerations, self.order)]

    def compile(self) -> None:
        """Compile the start's forms now (the step forms are compiled already), e.g.
        before timing a run."""
        if self._initial_solver is None:
            key = self.structure_key + "initial"
            F = None if form_cache.lookup(key, self.problem.comm) else self.problem.residual
            self._initial_solver = BlockSNES(F, self._unknowns_at_start(), self.problem.bcs,
                                             self.options, cache=(key, self._model_objects),
                                             step_scale=self.problem.configuration_norm(),
                                             links=self.problem.links,
                                             terms=self.problem.terms,
                                             force_scale=self.problem.force_scale,
                                             static=not self.problem.inertia)

    def initial_accelerations(self, t0: float, first_step: float | None = None) -> None:
        """Solve the residual at t0 for the accelerations (second order) and rates (first
        order), zero at the Dirichlet dofs (the rod starts at rest,
        rod/boundary_conditions.py), with the differential state fixed and the algebraic
        blocks (order 0) solved with them at their prescribed values (_start_algebraic
        then commits them); what starts at rest within a contact barrier is moved to
        where the barrier carries it, the accelerations solved again after each move
        (problem.rest_in_contact, given _solve_from_rest).  Friction
        (problem.friction_lookahead) reads the slip the ``first_step`` would make,
        v0 + h a0 (with None: v0, where the regularised law exerts no force: a rod at rest
        then starts frictionless).  With
        problem.starting_accelerations "zero" the second-order blocks' accelerations are
        then set to 0 (a state at rest; the first-order rates and algebraic blocks as
        solved).  A failed start (no step can be cut at t0) is an IntegrationError, the
        fields as they were given."""
        p = self.problem
        p.set_loads(t0)
        p.set_bcs(t0)
        self.compile()
        if 2 in self.order and (not p.links or p.scale_motions is not None) and \
                self._displaced():
            self._equilibrium_start(t0)
        rates = [f.function_space for f, k in zip(p.fields, self.order) if k]
        zeroed = [bc for bc in p.bcs if any(compat.contains(V, bc) for V in rates)]
        values = [np.array(bc.g.value) for bc in zeroed]
        initial = [f.x.array.copy() for f in p.fields]
        for bc in zeroed:
            bc.g.value[...] = 0.0
        lookahead = p.friction_lookahead if first_step is not None else None
        if lookahead is not None:
            lookahead.value = first_step
        try:
            self._start_solve(t0)
            if p.rest_in_contact is not None:
                p.rest_in_contact(self._solve_from_rest)
            if 0 in self.order:
                self._start_algebraic(t0)
        except (SolverError, IntegrationError) as err:
            for f, array in zip(p.fields, initial):     # the state as it was given
                f.x.array[:] = array
            raise IntegrationError(f"the start at t = {t0:.6g}: {err}" + (
                "; the start is the equilibrium with the loads and end motions at t0, "
                "sought from the starting state (the loads approached in parts down to "
                f"1/{2 ** (self.max_cuts + 1)} of them): apply the end motions gradually (a "
                "ramp or smooth_step history), or start nearer to it (a quasi-static rod's "
                "initial.shape is only Newton's first guess), or settle the start first "
                "(initial.equilibrium = true: from the starting shape in pseudo-time)"
                if not p.inertia else ""),
                t0) from err
        finally:
            for bc, value in zip(zeroed, values):
                bc.g.value[...] = value
            if lookahead is not None:
                lookahead.value = 0.0
        for i, a in enumerate(self._unknowns_at_start()):
            if self.order[i] == 2 and p.starting_accelerations == "zero":
                a.x.array[:] = 0.0
            if self.order[i]:
                self.alg_n[i].x.array[:] = a.x.array
        self._started = True
        self._declared_rest = p.starting_accelerations == "zero"

    def _start_solve(self, t0: float) -> None:
        """The start's solve at t0; a quasi-static one (no inertia: the positions and
        rotations are algebraic) whose Newton fails under its loads (not zero) is
        approached on a load path (_loaded_in_parts)."""
        p = self.problem
        given = [a.x.array.copy() for a in self._unknowns_at_start()]
        try:
            self._initial_solver.solve()
        except SolverError:
            if p.inertia or not any(np.any(load.at(t0)) for load in p.loads):
                raise
            for a, array in zip(self._unknowns_at_start(), given):
                a.x.array[:] = array
            self._loaded_in_parts(t0)

    def _loaded_in_parts(self, t0: float) -> None:
        """The loads at t0 approached from none (the given state is unloaded; a load
        constant in time puts all of it on the start, where cutting steps would not
        lessen it) on a load path (step_control.load_path): each part solved, checked
        and, below the whole load, committed (rotation vectors: a part turns a node by its
        own increment, which the chart bounds by a quarter turn).  Then the loads are
        whole."""
        p = self.problem

        def part(factor: float) -> None:
            p.set_loads(t0)
            p.scale_loads(factor)
            self._initial_solver.solve()
            self._checked(p)
            if factor < 1.0:
                p.after_step()

        try:
            load_path(part, self.max_cuts, self._unknowns_at_start())
        finally:
            p.set_loads(t0)

    def _solve_from_rest(self) -> None:
        """The start's accelerations solved again (problem.rest_in_contact moved the
        state), Newton from zero accelerations as the first solve (friction's sticking
        branch: from the last, sliding, answer it stalls)."""
        for a, k in zip(self._unknowns_at_start(), self.order):
            if k == 2:
                a.x.array[:] = 0.0
        self._initial_solver.solve()

    def _displaced(self) -> bool:
        """Whether a Dirichlet value of a second-order block at the time set differs from
        the state (an end of a dynamic rod displaced at t0), on any rank, by more than
        round-off (a curved start's end rotation: theta_end = c^-1(conj(q) q) ~ 1e-17).
        (A problem with multipoint constraints, rods joined or an oblique support, is
        checked only if it scales its motions: its constrained assembly has no path of
        Dirichlet values, BlockSNES.solve's sub-solves.)"""
        p, local = self.problem, False
        for f, k in zip(p.fields, self.order):
            for bc in p.bcs if k == 2 else ():
                if compat.contains(f.function_space, bc):
                    values = f.x.array.copy()
                    bc.set(values)
                    local = local or bool(np.any(np.abs(values - f.x.array) > 1e-12))
        return largest_on_ranks(p.comm, float(local)) > 0.0   # (a pickled allreduce: ~20 us)

    def _equilibrium_start(self, t0: float) -> None:
        """The consistent start of a dynamic problem whose prescribed values at t0 differ
        from its state: its second-order blocks (positions, rotations) solved at rest (zero
        velocities and accelerations) in equilibrium with them, approached in
        parts (start_parts of problem.motion_turn, problem.scale_motions: each
        committed, so that an end may turn by any angle; without them, sub-solves of the
        Dirichlet values, BlockSNES.solve), the first-order blocks' rates with them;
        checked and committed.  The first step then starts from equilibrium instead of a
        jump.  (A refused start leaves the fields as given, a rod's stored rotations as
        its last committed part turned them.)"""
        p = self.problem
        unknowns = [f if k == 2 else u
                    for f, u, k in zip(p.fields, self._unknowns_at_start(), self.order)]
        key = self.structure_key + "equilibrium"
        solver = BlockSNES(None if form_cache.lookup(key, p.comm) else p.residual, unknowns, p.bcs,
                           self.options, cache=(key, self._model_objects),
                           step_scale=p.configuration_norm(), links=p.links,
                           terms=p.terms, force_scale=p.force_scale,
                           static=not p.inertia)
        initial = [f.x.array.copy() for f in p.fields]
        try:
            if p.scale_motions is None:
                solver.solve(sub_solves=EQUILIBRIUM_SUB_SOLVES)
                self._checked(p)
            else:
                self._committed_path(solver, t0)
        except SolverError as err:
            for f, array in zip(p.fields, initial):
                f.x.array[:] = array
            raise IntegrationError(f"the start at t = {t0:.6g} in equilibrium with the end "
                                   f"motions' values there: {err}; start them from 0 (a ramp "
                                   "or smooth_step)", t0) from err
        finally:
            if p.scale_motions is not None:
                p.scale_motions(1.0)
                p.set_bcs(t0)
        p.after_step()

    @staticmethod
    def _checked(p) -> None:
        reason = p.check_step()
        if reason:
            raise SolverError(reason, 0)

    def _committed_path(self, solver, t0: float) -> None:
        """The motions' values at t0 reached in n = start_parts parts (scaled by k/n:
        problem.scale_motions), each solved, checked and committed (after_step): a part
        turns a node by its own rotation increment, which the chart bounds by a quarter
        turn (rotation_vector.py), so the parts grow with the ends' largest turn."""
        p = self.problem
        n = start_parts(p.motion_turn(t0) if p.motion_turn is not None else 0.0)
        for k in range(1, n + 1):
            p.scale_motions(k / n)
            p.set_bcs(t0)
            solver.solve()
            self._checked(p)
            if k < n:
                p.after_step()

    def _start_algebraic(self, t0: float) -> None:
        """After the start's solve: its algebraic state is checked (check_step: a
        refusal is a SolverError) and committed (after_step), and the algebraic blocks'
        rates are 0 (t0 is their first state)."""
        reason = self.problem.check_step()
        if reason:
            raise SolverError(reason, 0)
        self.problem.after_step()
        for i, k in enumerate(self.order):
            if k == 0:
                self.problem.rates[i].x.array[:] = 0.0

    def _restore(self) -> None:
        """Back to the state at the start of the failed step (one-step method: exact)."""
        p = self.problem
        for i, f in enumerate(p.fields):
            f.x.array[:] = self.y_n[i].x.array
            p.rates[i].x.array[:] = self.v_n[i].x.array
            if p.accelerations[i] is not None:
                p.accelerations[i].x.array[:] = self.acc_n[i].x.array

    def run(self, t0: float, t_end: float, dt: float, observer=None) -> float:
        """From t0 to t_end; ``observer(t, self)`` at t0 and after every accepted step.
        Fixed steps (no tolerance): equal steps of at most dt (stepping.nominal_steps of
        them); a step whose Newton fails is redone as two half steps, at most
        ``max_cuts`` halvings deep.  Error control: dt is the first step (later runs
        continue with the controller's ``next_dt``), steps clipped to t_end; a step is
        redone smaller if its local error exceeds the tolerance or its Newton fails, at
        most ``max_cuts`` times in a row.  IntegrationError when that is exhausted, the
        last accepted state kept."""
        check_run(t0, t_end, dt, self.problem, adaptive=self.control is not None)
        first = (self.control.limited(self.next_dt or dt) if self.control is not None
                 else (t_end - t0) / nominal_steps(t0, t_end, dt))
        if not self._started:
            self.initial_accelerations(t0, min(first, t_end - t0))
        if observer:
            observer(t0, self)
        if self.control is not None:
            return self._run_adaptive(t0, t_end, first, observer)
        n = nominal_steps(t0, t_end, dt)
        h = (t_end - t0) / n
        for k in range(n):
            self._substep(t0 + k * h, h, self.max_cuts, observer)
        return t_end

    def _run_adaptive(self, t: float, t_end: float, h: float, observer) -> float:
        self._rejections = 0

        def succeeded(t_new: float, h_try: float, h: float) -> float:
            if observer:
                observer(t_new, self)
            return self._next_step(h_try, h)

        t, self.next_dt = march(t, t_end, h, self.step, self._rejected, succeeded)
        return t

    def _next_step(self, h_try: float, h: float) -> float:
        """The step after an accepted one of h_try (h: the step before clipping)."""
        proposal = h_try * self.control.growth(self.last_error, self._rejections > 0)
        after_rejection, self._rejections = self._rejections, 0
        # a step clipped to t_end does not shrink the next one
        return self.control.limited(max(proposal, h) if h_try < h and not after_rejection
                                    else proposal)

    def _rejected(self, t: float, h: float, err: SolverError) -> float:
        """The step after a rejected one (IntegrationError after max_cuts in a row)."""
        self.stats.rejected += 1
        self._rejections += 1
        if self._rejections > self.max_cuts:
            raise step_failure(t, self.max_cuts, h, err, self.problem) from err
        if isinstance(err, StepRejected):
            return h * self.control.growth(err.error)
        return CUT_FACTOR * h

    def _substep(self, t: float, h: float, cuts_left: int, observer) -> None:
        try:
            self.step(t, h)
        except SolverError as err:
            self.stats.rejected += 1
            if cuts_left == 0:
                raise step_failure(t, self.max_cuts, h, err, self.problem) from err
            self._substep(t, h / 2, cuts_left - 1, observer)
            self._substep(t + h / 2, h / 2, cuts_left - 1, observer)
            return
        if observer:
            observer(t + h, self)

    def _views(self) -> list:
        """Per block the arrays step() reads and writes (views, fetched once: a DOLFINx
        array property costs ~1 us, 60 of them per step at 32 cells): y, its rate, y_n,
        v_n, the algorithmic acceleration (rate), the acceleration and its old value."""
        p = self.problem
        return [(f.x.array, p.rates[i].x.array, self.y_n[i].x.array, self.v_n[i].x.array,
                 self.alg_n[i].x.array,
                 None if p.accelerations[i] is None else p.accelerations[i].x.array,
                 None if p.accelerations[i] is None else self.acc_n[i].x.array)
                for i, f in enumerate(p.fields)]

    def _stacked_blocks(self) -> list:
        """[(order, [blocks])]: the blocks of the same time order and size, whose updates
        after a step are one matrix product (_updates)."""
        stacks = {}
        for i, (y, *_) in enumerate(self._arrays):
            stacks.setdefault((self.order[i], y.size), []).append(i)
        return [(order, blocks) for (order, _), blocks in stacks.items()]

    def step(self, t: float, h: float) -> int:
        """One step from t to t + h; raises SolverError (state restored)."""
        p = self.problem
        if not self._started:
            self.initial_accelerations(t, h)
        fresh, self._dt_last = h != self._dt_last, h
        if fresh:           # (only this method sets it; a Constant's value costs ~3 us)
            self.dt.value = h
        hh = 0.5 * h * h
        for (y, r, y_n, v_n, alg, acc, acc_n), order in zip(self._arrays, self.order):
            y_n[:] = y
            v_n[:] = r
            if acc is not None:
                acc_n[:] = acc
            # predictor: algorithmic acceleration / rate kept (algebraic: the last rate)
            y += h * v_n + hh * alg if order == 2 else h * alg if order == 1 else h * v_n
        p.set_loads(t + h)
        p.set_bcs(t + h)
        if p.terms:
            self._tell_rates(self._rate_maps(h))
        try:
            its = self.solver.solve(fresh_jacobian=fresh)
            for arrays in self._arrays:
                if not _finite(arrays[0]):
                    raise SolverError("non-finite solution", its)
            reason = p.check_step()
            if reason:
                raise SolverError(reason, its)
        except SolverError:
            self._restore()
            raise
        finally:
            if p.terms:
                self._tell_rates(None)
        if self.local_error is not None:     # error control: accept or reject
            self._check_local_error(h)
        self._declared_rest = False
        for (_, r, _, _, alg, acc, _), (alg_new, r_new, acc_new) in zip(self._arrays,
                                                                         self._updates(h)):
            alg[:] = alg_new
            r[:] = r_new
            if acc is not None:
                acc[:] = acc_new
        p.after_step()
        self.stats.newton_iterations += its
        self.stats.steps += 1
        return its

    def _rate_maps(self, h: float) -> list:
        """Per block the rate at t_{n+1} as an affine map of the block's unknowns y_{n+1}
        (_np_update's rate row): (slope, intercept) with rate = slope y + intercept."""
        maps = []
        for i, (_, _, y_n, *_) in enumerate(self._arrays):
            slope = 1 / h if self.order[i] == 0 else self._update_matrix(self.order[i], h)[1, 0]
            maps.append((slope, self._np_update(i, -y_n, h)[1]))
        return maps

    def _tell_rates(self, maps) -> None:
        """Terms whose forces depend on the rates (segment friction: ``set_rates``) get
        the step's rate maps, or None after it (they then read the rate fields)."""
        for term in self.problem.terms:
            if hasattr(term, "set_rates"):
                term.set_rates(maps)

    def _check_local_error(self, h: float) -> None:
        """StepRejected (state restored) if the solved step's local error exceeds the
        tolerance; its weighted value in ``last_error``.  The first step from a start
        whose accelerations were set to 0 (starting_accelerations "zero": a state declared
        at rest, its imbalance not carried) is not measured: its estimate h^2 c (a_1 - 0)
        is that imbalance, not a truncation error, and falls only as h^2 (a polyline's
        corners: rotational accelerations ~1e8 rad/s^2, the steps cut below 1e-5 s and the
        run failing at t0); it is taken as a fixed step is, the next one as long."""
        if self._declared_rest:
            self.last_error = 1.0
            return
        self.last_error = self.local_error(h, self._arrays)
        if not self.last_error <= 1.0:
            self._restore()
            raise StepRejected(self.last_error)

    def assembly_timings(self) -> dict[str, float]:
        """Seconds spent so far in residual and Jacobian assembly."""
        return dict(self.solver.timings)

    def checkpoint_state(self) -> dict:
        """Functions (besides problem.fields) a checkpoint stores: rates, accelerations,
        algorithmic accelerations (one-step method: nothing else), and the error
        control's next step."""
        p = self.problem
        functions = {f"rate_{i}": r for i, r in enumerate(p.rates)}
        functions |= {f"acceleration_{i}": a for i, a in enumerate(p.accelerations)
                      if a is not None}
        functions |= {f"algorithmic_{i}": a for i, a in enumerate(self.alg_n)}
        return {"functions": functions, "history_steps": 0, "next_dt": self.next_dt}

    def restore_state(self, state: dict) -> None:
        """After the checkpoint's functions were read: no initial solve again; error
        control continues with the checkpoint's next step."""
        self._started = True
        self.next_dt = state.get("next_dt")
