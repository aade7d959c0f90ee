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
d = h ((1 - gamma) b_n + gamma b_{n+1}) and the same filter between b and y'.
alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f - alpha_m,
beta = (gamma + 1/2)^2 / 4: second order, unconditionally stable, high-frequency
spectral radius rho_inf.  The start needs consistent accelerations (solved at t0).
"""

from __future__ import annotations

import dolfinx.fem as fem
import numpy as np
import ufl

from .. import form_cache
from ..solvers import BlockSNES, SolverError
from .schemes import alpha_rho_inf
from .stepping import IntegrationError, StepStats, check_run, nominal_steps


def default_options(comm) -> dict:
    """The integrator's solver defaults.

    One rank: PETSc's own LU in the natural order (the banded order of a 1-D mesh; safe
    without pivoting: there is no saddle point).  Several ranks: GMRES preconditioned by
    that LU on each rank's diagonal block (block Jacobi): the preconditioned operator is
    the identity plus a rank <= 2 b (ranks - 1) coupling through the interface nodes, so
    GMRES converges in a few iterations (2.6x cheaper than MUMPS at 2e4 cells on 2 ranks,
    same tip to all digits, docs/performance.md).  Newton: rtol 1e-6 (the predictor's
    residual is O(dt^3) small already: the benchmark tip errors are unchanged to 4
    digits); each step's Newton starts with a new Jacobian and LU and keeps them while
    every iteration reduces the residual 10-fold (solvers.BlockSNES,
    jacobian_reuse_ratio): 1.0-1.5 Jacobians per step on the benchmark scenes instead of
    1.9-2.6 with a refresh every second iteration, fewer step cuts (docs/performance.md).
    """
    options = {"jacobian_reuse_ratio": 0.1, "snes_rtol": 1e-6}
    if comm.size == 1:
        options.update(pc_factor_mat_solver_type="petsc", pc_factor_mat_ordering_type="natural")
    else:
        options.update(ksp_type="gmres", ksp_rtol=1e-12, ksp_atol=1e-14, pc_type="bjacobi",
                       sub_pc_type="lu", sub_pc_factor_mat_ordering_type="natural")
    return options


def solver_settings(comm, solver_options: dict | None) -> dict:
    """default_options updated by ``solver_options``; options that set PETSc's Jacobian
    lags (e.g. solvers.JACOBIAN_REUSE) replace the default rule (jacobian_reuse_ratio)."""
    options = default_options(comm)
    if any(k.startswith("snes_lag_") for k in solver_options or {}):
        del options["jacobian_reuse_ratio"]
    return {**options, **(solver_options or {})}


def alpha_parameters(rho_inf: float):
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf must be in [0, 1], got {rho_inf}")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    gamma = 0.5 + af - am
    beta = 0.25 * (gamma + 0.5) ** 2
    return am, af, gamma, beta


def _copy(f, tag):
    g = fem.Function(f.function_space, name=f"{f.name}_{tag}")
    g.x.array[:] = f.x.array
    return g


class LieGeneralizedAlpha:
    """Advance a second-order problem; ``problem.after_step`` moves the rotation
    increments into the stored rotations (and resets them to 0).  The interface of
    TimeStepper (run, step, stats, checkpoint_state), which returns this integrator for a
    SecondOrderProblem."""

    def __init__(self, problem, rho_inf: float = 0.8, solver_options=None, max_cuts: int = 6):
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
                                                      rho_inf)
        objects = [*self._model_objects, *self.y_n, *self.v_n,
                   *(a for a in self.acc_n if a is not None), *self.alg_n, self.dt]
        F = None if form_cache.lookup(self.structure_key) else self._step_forms()
        self.options = options = solver_settings(mesh.comm, solver_options)
        self.solver = BlockSNES(F, y, problem.bcs, options,
                                cache=(self.structure_key, objects))
        self._arrays = self._views()
        self.stats = StepStats()
        self._started = False
        self._dt_last = None
        self._initial_solver = None

    @classmethod
    def for_scheme(cls, problem, scheme: str | None, solver_options=None, max_cuts: int = 6):
        """TimeStepper's arguments: ``scheme`` None (rho_inf 0.8) or 'generalized_alpha'
        ['RHO'] (schemes.alpha_rho_inf); a first-order scheme is refused."""
        if scheme is not None and not scheme.startswith("generalized_alpha"):
            raise ValueError(f"scheme {scheme!r}: a rod with rotation-vector unknowns is "
                             "advanced by generalized_alpha[:rho_inf] on the rotation group "
                             "only; for another scheme build RodModel(..., "
                             "rotations='quaternion')")
        rho_inf = 0.8 if scheme is None else alpha_rho_inf(scheme)
        return cls(problem, rho_inf, solver_options, max_cuts)

    @property
    def description(self) -> str:
        return f"generalized-alpha on the rotation group (rho_inf = {self.rho_inf:g})"

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
        if self.order[i] == 2:
            a_new = (d - h * vn - h * h * (0.5 - b) * alg) / (h * h * b)
            v_new = vn + h * ((1 - g) * alg + g * a_new)
            acc_new = ((1 - am) * a_new + am * alg - af * self.acc_n[i]) / (1 - af)
            return v_new, acc_new
        b_new = (d - h * (1 - g) * alg) / (h * g)
        return ((1 - am) * b_new + am * alg - af * vn) / (1 - af), None

    def _np_update(self, i, d, h):
        am, af, g, b = self.am, self.af, self.gamma, self.beta
        vn, alg = self.v_n[i].x.array, self.alg_n[i].x.array
        if self.order[i] == 2:
            a_new = (d - h * vn - h * h * (0.5 - b) * alg) / (h * h * b)
            v_new = vn + h * ((1 - g) * alg + g * a_new)
            acc_new = ((1 - am) * a_new + am * alg - af * self.acc_n[i].x.array) / (1 - af)
            return a_new, v_new, acc_new
        b_new = (d - h * (1 - g) * alg) / (h * g)
        return b_new, ((1 - am) * b_new + am * alg - af * vn) / (1 - af), None

    def _unknowns_at_start(self) -> list:
        p = self.problem
        return [a if a is not None else r for a, r in zip(p.accelerations, p.rates)]

    def compile(self) -> None:
        """Compile the start's forms now (the step forms are compiled already), e.g.
        before timing a run."""
        if self._initial_solver is None:
            key = self.structure_key + "initial"
            F = None if form_cache.lookup(key) else self.problem.residual
            self._initial_solver = BlockSNES(F, self._unknowns_at_start(), self.problem.bcs,
                                             cache=(key, self._model_objects))

    def initial_accelerations(self, t0: float) -> None:
        """Solve the residual at t0 for the accelerations (second order) and rates (first
        order) with the state fixed, zero at the Dirichlet dofs (the rod starts at rest,
        rod/boundary_conditions.py)."""
        p = self.problem
        p.set_loads(t0)
        p.set_bcs(t0)
        self.compile()
        values = [np.array(bc.g.value) for bc in p.bcs]
        for bc in p.bcs:
            bc.g.value[...] = 0.0
        try:
            self._initial_solver.solve()
        finally:
            for bc, value in zip(p.bcs, values):
                bc.g.value[...] = value
        for i, a in enumerate(self._unknowns_at_start()):
            self.alg_n[i].x.array[:] = a.x.array
        self._started = True

    def _restore(self) -> None:
        """Back to the state at the start of the failed step (one-step method: exact)."""
        p = self.problem
        for i, f in enumerate(p.fields):
            f.x.array[:] = self.y_n[i].x.array
            p.rates[i].x.array[:] = self.v_n[i].x.array
            if p.accelerations[i] is not None:
                p.accelerations[i].x.array[:] = self.acc_n[i].x.array

    def run(self, t0: float, t_end: float, dt: float, observer=None) -> float:
        """Equal steps of at most dt from t0 to t_end (stepping.nominal_steps of them);
        ``observer(t, self)`` at t0 and after every accepted step.  A step whose Newton
        fails is redone as two half steps, at most ``max_cuts`` halvings deep
        (IntegrationError after that, the last accepted state kept)."""
        check_run(t0, t_end, dt)
        if not self._started:
            self.initial_accelerations(t0)
        if observer:
            observer(t0, self)
        n = nominal_steps(t0, t_end, dt)
        h = (t_end - t0) / n
        for k in range(n):
            self._substep(t0 + k * h, h, self.max_cuts, observer)
        return t_end

    def _substep(self, t: float, h: float, cuts_left: int, observer) -> None:
        try:
            self.step(t, h)
        except SolverError as err:
            self.stats.rejected += 1
            if cuts_left == 0:
                raise IntegrationError(f"time step failed at t = {t:.6g} after "
                                       f"{self.max_cuts} step cuts (last dt = {h:.3g}): "
                                       f"{err}", t) from err
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

    def step(self, t: float, h: float) -> int:
        """One step from t to t + h; raises SolverError (state restored)."""
        p = self.problem
        if not self._started:
            self.initial_accelerations(t)
        self.dt.value = h
        for i, (y, r, y_n, v_n, alg, acc, acc_n) in enumerate(self._arrays):
            y_n[:], v_n[:] = y, r
            if acc is not None:
                acc_n[:] = acc
            # predictor: algorithmic acceleration / rate kept
            y += h * v_n + 0.5 * h * h * alg if self.order[i] == 2 else h * alg
        p.set_loads(t + h)
        p.set_bcs(t + h)
        fresh, self._dt_last = h != self._dt_last, h
        try:
            its = self.solver.solve(fresh_jacobian=fresh)
            if not all(np.isfinite(arrays[0]).all() for arrays in self._arrays):
                raise SolverError("non-finite solution", its)
        except SolverError:
            self._restore()
            raise
        for i, (y, r, y_n, _, alg, acc, _) in enumerate(self._arrays):
            alg_new, r[:], acc_new = self._np_update(i, y - y_n, h)
            alg[:] = alg_new
            if acc is not None:
                acc[:] = acc_new
        p.after_step()
        self.stats.newton_iterations += its
        self.stats.steps += 1
        return its

    def assembly_timings(self) -> dict[str, float]:
        """Seconds spent so far in residual and Jacobian assembly."""
        return dict(self.solver.timings)

    def checkpoint_state(self) -> dict:
        """Functions (besides problem.fields) a checkpoint stores: rates, accelerations,
        algorithmic accelerations (one-step method: nothing else)."""
        p = self.problem
        functions = {f"rate_{i}": r for i, r in enumerate(p.rates)}
        functions |= {f"acceleration_{i}": a for i, a in enumerate(p.accelerations)
                      if a is not None}
        functions |= {f"algorithmic_{i}": a for i, a in enumerate(self.alg_n)}
        return {"functions": functions, "history_steps": 0}

    def restore_state(self, state: dict) -> None:
        """After the checkpoint's functions were read: no initial solve again."""
        self._started = True
