"""Per-step time integration: a scheme turns F(t, y, dy/dt) into a step residual that
BlockSNES solves.  Step cutting recovers from Newton failures; an unrecoverable failure
raises IntegrationError and leaves every accepted step with the observer.
"""

from __future__ import annotations

import warnings
from typing import Callable

import dolfinx.fem as fem
import numpy as np
import ufl

from ..checks import MAX_STEP_CUTS, PREDICTOR, SCHEME
from ..fem import form_cache
from ..fem.assembly import monolithic_layout
from ..fem.problem import SecondOrderProblem, SemiDiscreteProblem
from ..fem.solvers import BlockSNES, SolverError
from ..mpi import largest_on_ranks
from .lie_alpha import solver_settings
from .schemes import Scheme, get_scheme
from .step_control import (CUT_FACTOR, ROUND_OFF, IntegrationError, StepStats, check_run,
                           grown, load_path, march, nominal_steps, same_step, step_failure)

__all__ = ["SchemeStepper", "IntegrationError", "StepStats", "step_forms"]


def _copy(f: fem.Function) -> fem.Function:
    g = fem.Function(f.function_space, name=f"{f.name}_old")
    g.x.array[:] = f.x.array
    return g


def stage_loads(problem: SemiDiscreteProblem, scheme: Scheme) -> list:
    """Per stage (c_k, [(stage load constant, TimeDependentValue)]): the loads of stage k
    are set at t_n + c_k dt."""
    mesh = problem.fields[0].function_space.mesh
    return [(st.c, [(fem.Constant(mesh, np.array(load.constant.value, dtype=float)), load)
                    for load in problem.loads]) for st in scheme.stages]


def step_forms(problem: SemiDiscreteProblem, scheme: Scheme, history, dt, loads=None):
    """The UFL residual of one step, sum_k w_k F(t_k, Y_k, Ydot_k) (schemes.py), one form
    per block, and the stages' loads (``loads``, else new: stage_loads)."""
    y, ydot = problem.fields, problem.rates
    y_n, y_nm1, ydot_n = history
    loads = loads or stage_loads(problem, scheme)
    F = [0] * len(y)
    for st, (_, stage) in zip(scheme.stages, loads):
        mapping = {load.constant: c for c, load in stage}
        for i in range(len(y)):
            mapping[y[i]] = st.state(y[i], y_n[i], y_nm1[i])
            mapping[ydot[i]] = st.rate(y[i], y_n[i], y_nm1[i], ydot_n[i], dt)
        F = [Fi + st.w * ufl.replace(Ri, mapping) for Fi, Ri in zip(F, problem.residual)]
    return F, loads


class _StepResidual:
    """The compiled step residual of one scheme (dt, loads and stage times are Constants),
    its kernels shared by every problem of the same structure (form_cache)."""

    def __init__(self, problem: SemiDiscreteProblem, scheme: Scheme, history, dt, options):
        self.problem, self.scheme = problem, scheme
        self.stage_loads = stage_loads(problem, scheme)
        # the layout in the key: scifem's real space has DG0's UFL signature (DOLFINx 0.9)
        mixed = monolithic_layout(problem.fields)
        self.key = key = form_cache.structure_key(problem.residual, "step", scheme.name, mixed,
                                                       structure=problem.structure)
        objects = [*form_cache.registry(problem.residual), *(f for h in history for f in h), dt,
                   *(c for _, stage in self.stage_loads for c, _ in stage)]
        F = None if form_cache.lookup(key, problem.comm) else step_forms(
            problem, scheme, history, dt, self.stage_loads)[0]
        stages = [(st.w, st.a) for st in scheme.stages]      # terms: a rod's segment contact
        terms = [term.for_step(stages, problem.fields, *history[:2]) for term in problem.terms]
        self.solver = BlockSNES(F, problem.fields, problem.bcs, options, cache=(key, objects),
                                step_scale=problem.configuration_norm(),
                                links=problem.links, terms=terms,
                                force_scale=problem.force_scale,
                                static=not problem.inertia)
        self._dt_last = None

    def loads_change(self, t_n: float, dt: float, unloaded: bool) -> bool:
        """Whether a stage's loads differ from a load path's start (solve)."""
        return any(np.any(load.at(t_n + c * dt) != (0.0 if unloaded else load.at(t_n)))
                   for c, loads in self.stage_loads for _, load in loads)

    def solve(self, t_n: float, dt: float, sub_solves: int = 1, factor: float = 1.0,
              unloaded: bool = False) -> int:
        """The step from t_n; with ``factor`` < 1 a part of its loads on a load path:
        L_0 + factor (L(t) - L_0) from L_0 = L(t_n), the last accepted state's loads, or
        0 (``unloaded``: before the first step)."""
        for c, loads in self.stage_loads:
            for const, load in loads:
                value = load.at(t_n + c * dt)
                if factor != 1.0:
                    base = 0.0 if unloaded else load.at(t_n)
                    value = base + factor * (value - base)
                const.value[...] = value
        self.problem.set_bcs(t_n + dt)
        fresh, self._dt_last = dt != self._dt_last, dt  # a reused Jacobian holds the old dt
        return self.solver.solve(fresh_jacobian=fresh, sub_solves=sub_solves)


class SchemeStepper:
    """Advance a SemiDiscreteProblem with a per-step scheme (integrators/choice.py picks
    it for a problem; ``TimeStepper`` is the one-liner).

    observer(t, stepper) is called at t0 and after every accepted step; the state is in
    ``problem.fields`` and the rate estimate at t in ``problem.rates``.
    predictor:  Newton's initial guess, "linear" y_n + dt dy/dt_n (an O(dt^2) guess:
                about one Newton iteration fewer per step on smooth dynamics) or
                "constant" y_n.
    history_steps: accepted steps since the start or the last restart, capped at 2
                (Scheme.for_step picks the startup and second-step schemes from it);
                part of a checkpoint's state.  The history restarts (0) after a failed
                step and at a run() that does not continue the last one (its t0 is not
                where that run ended, or the state was changed in between); a scheme
                that reads y_{n-1} (BDF2) restarts for a step whose size differs from
                the last one's (the growth after a cut, a clipped final step).
    """

    PREDICTORS = ("linear", "constant")

    def __init__(self, problem: SemiDiscreteProblem, scheme: str | None = None,
                 solver_options: dict | None = None, max_cuts: int = MAX_STEP_CUTS,
                 predictor: str = PREDICTOR, tolerance: float | None = None):
        if tolerance is not None:
            raise ValueError("tolerance: error-controlled steps exist for a rod with "
                             "rotation-vector unknowns (generalized-alpha on the rotation "
                             "group) only; this problem is advanced with fixed steps (or "
                             "use TSIntegrator(..., adaptive=True))")
        if predictor not in self.PREDICTORS:
            raise ValueError(f"predictor must be one of {self.PREDICTORS}, got {predictor!r}")
        self.predictor = predictor
        self.problem = problem
        self.scheme = get_scheme(scheme or SCHEME)
        # rotation vectors (no saddle point): the banded LU of the rotation-group integrator
        self._charted = lie = isinstance(problem, SecondOrderProblem) and problem.lie_group
        self.options = solver_settings(problem.comm, solver_options, False) if lie \
            else solver_options
        self.max_cuts = max_cuts
        self.y_n = [_copy(f) for f in problem.fields]
        self.y_nm1 = [_copy(f) for f in problem.fields]
        self.ydot_n = [_copy(f) for f in problem.rates]
        self.dt = fem.Constant(problem.fields[0].function_space.mesh, 1.0)
        self._residuals: dict[str, _StepResidual] = {}
        self.stats = StepStats()
        self.history_steps = 0
        self._last_step: float | None = None    # size of the last accepted step
        self._end: tuple[float, list] | None = None   # where the last run ended: t, state
        self._sub_solves = 1    # 2^cuts: a cut step's Dirichlet values are approached

    def _residual(self, scheme: Scheme) -> _StepResidual:
        if scheme.name not in self._residuals:
            history = (self.y_n, self.y_nm1, self.ydot_n)
            self._residuals[scheme.name] = _StepResidual(
                self.problem, scheme, history, self.dt, self.options)
        return self._residuals[scheme.name]

    def compile(self) -> None:
        """Compile the step forms of the scheme and of its startup scheme now (e.g. before
        timing a run), rather than at the first step that needs them."""
        self._residual(self.scheme)
        if self.scheme.startup:
            self._residual(get_scheme(self.scheme.startup))

    @property
    def structure_key(self) -> str:
        """The form-cache key of this stepper's step forms (form_cache.py)."""
        return self._residual(self.scheme).key

    def step_forms(self, scheme: Scheme | None = None) -> list:
        """The UFL step residual (one form per block) of ``scheme`` (default: this
        stepper's), on this stepper's history and dt, without compiling it."""
        history = (self.y_n, self.y_nm1, self.ydot_n)
        return step_forms(self.problem, scheme or self.scheme, history, self.dt)[0]

    def assembly_timings(self) -> dict[str, float]:
        """Seconds spent so far in residual and Jacobian assembly (all schemes' solvers)."""
        total = {"residual": 0.0, "jacobian": 0.0}
        for res in self._residuals.values():
            for key, seconds in res.solver.timings.items():
                total[key] += seconds
        return total

    @property
    def description(self) -> str:
        return f"TimeStepper with {self.scheme.name}"

    def checkpoint_state(self) -> dict:
        """Functions (besides problem.fields) and flags a checkpoint stores."""
        return {"functions": {**{f"rate_{i}": r for i, r in enumerate(self.problem.rates)},
                              **{f"previous_{i}": p for i, p in enumerate(self.y_nm1)}},
                "history_steps": self.history_steps, "last_step": self._last_step,
                "end_time": None if self._end is None else self._end[0]}

    def restore_state(self, state: dict) -> None:
        """After the checkpoint's functions were read: the next run from the
        checkpoint's time continues its history."""
        self.history_steps = int(state["history_steps"])
        self._last_step = state.get("last_step")
        end = state.get("end_time")
        self._end = None if end is None else (end, self._state())

    def _state(self) -> list[np.ndarray]:
        return [f.x.array.copy() for f in self.problem.fields]

    def _continues(self, t0: float, dt: float) -> bool:
        """run(t0, ...) continues the last run: it ended at t0 with the state as it is
        now (the same on every rank)."""
        if self._end is None or abs(t0 - self._end[0]) > ROUND_OFF * dt:
            return False
        changed = any(not np.array_equal(f.x.array, y)
                      for f, y in zip(self.problem.fields, self._end[1]))
        return largest_on_ranks(self.problem.comm, float(changed)) == 0.0

    def _restore(self) -> None:
        for fn, f in zip(self.y_n, self.problem.fields):
            f.x.array[:] = fn.x.array

    def step(self, t: float, dt: float) -> None:
        """One step from t (state in problem.fields) to t + dt; raises SolverError."""
        scheme = self.scheme.for_step(self.history_steps, same_step(dt, self._last_step))
        for fn, f, rn, r in zip(self.y_n, self.problem.fields, self.ydot_n, self.problem.rates):
            fn.x.array[:] = f.x.array
            rn.x.array[:] = r.x.array
            if self.predictor == "linear":
                f.x.array[:] += dt * r.x.array
        self.dt.value = dt
        jump = False
        try:
            its = self._residual(scheme).solve(t, dt, self._sub_solves)
        except SolverError:
            self._restore()
            if self.problem.inertia or not self._residual(scheme).loads_change(
                    t, dt, unloaded=self._unloaded()):
                raise
            its, jump = self._on_load_path(scheme, t, dt), True
        if not all(np.isfinite(f.x.array).all() for f in self.problem.fields):
            self._restore()
            raise SolverError("non-finite solution", its)
        reason = self.problem.check_step()
        if reason:
            self._restore()
            raise SolverError(reason, its)
        for f, fn, fnm1, rate, rate_n in zip(self.problem.fields, self.y_n, self.y_nm1,
                                              self.problem.rates, self.ydot_n):
            rate.x.array[:] = scheme.rate_after_step(f.x.array, fn.x.array, fnm1.x.array,
                                                     rate_n.x.array, dt)
            fnm1.x.array[:] = fn.x.array
        if jump:    # a load the steps do not resolve: rates and history start after it
            for rate in self.problem.rates:
                rate.x.array[:] = 0.0
        self._after_step()
        self.history_steps = 0 if jump else min(self.history_steps + 1, 2)
        self._last_step = dt
        self.stats.steps += 1
        self.stats.newton_iterations += its

    def _on_load_path(self, scheme: Scheme, t: float, dt: float) -> int:
        """A static step (no inertia: a quasi-static rod) whose Newton failed under its
        loads, which a smaller step would not lessen (a load constant in time is all on
        the first step): the step's loads approached from the last accepted state's (none
        before the first step from a given state, which is unloaded: _unloaded) on a load path
        (step_control.load_path), each part solved from the last; SolverError (state
        restored) if that fails.  The step then took a load it does not resolve (a jump):
        step() starts the rates (0) and the history (the startup scheme) after it."""
        residual, first, its = self._residual(scheme), self._unloaded(), [0]

        def part(factor: float) -> None:
            its[0] += residual.solve(t, dt, self._sub_solves, factor, unloaded=first)

        try:
            load_path(part, self.max_cuts, self.problem.fields)
        except SolverError:
            self._restore()
            raise
        return its[0]

    def _unloaded(self) -> bool:
        """Whether the state holds none of the loads: the given state before the first
        step, unless it was settled or read from a run (problem.start_loaded)."""
        return self.stats.steps == 0 and not self.problem.start_loaded

    def _after_step(self) -> None:
        """problem.after_step, and the history moved with what it changes: a rotation
        increment theta goes into the stored rotations (q_{n+1} = q_n c(theta), theta <- 0),
        so the state before the step is -theta in the new chart (q_n = q_{n+1} c(-theta),
        exact for the Cayley map), which multistep rates (BDF2) and the predictor read."""
        if not self._charted:
            self.problem.after_step()
            return
        before = [f.x.array.copy() for f in self.problem.fields]
        self.problem.after_step()
        for f, fnm1, b in zip(self.problem.fields, self.y_nm1, before):
            fnm1.x.array[:] += f.x.array - b

    def _cut(self, t: float, h_try: float, cuts: int, err: SolverError) -> float:
        """The step after a failure at t (IntegrationError after max_cuts cuts)."""
        self.stats.rejected += 1
        if cuts > self.max_cuts:
            raise step_failure(t, self.max_cuts, h_try, err, self.problem) from err
        h = CUT_FACTOR * h_try
        if self.scheme.startup and get_scheme(self.scheme.startup).order < self.scheme.order:
            warnings.warn(f"step at t = {t:.6g} cut to dt = {h:.3g} ({err}); "
                          f"{self.scheme.name} restarts with {self.scheme.startup}, "
                          "which is first-order accurate", RuntimeWarning, stacklevel=5)
        self.history_steps = 0
        return h

    def run(self, t0: float, t_end: float, dt: float,
            observer: Callable[[float, "SchemeStepper"], None] | None = None) -> float:
        """Integrate from t0 to t_end with nominal step dt, cutting steps on failure.
        A run from where the last one ended, on its end state, continues its history;
        any other starts afresh (the startup scheme)."""
        check_run(t0, t_end, dt, self.problem)
        if not self._continues(t0, dt):
            self.history_steps = 0
        self._sub_solves = 1
        if observer:
            observer(t0, self)
        cuts = 0

        def failed(t: float, h_try: float, err: SolverError) -> float:
            nonlocal cuts
            cuts += 1
            h = self._cut(t, h_try, cuts, err)
            self._sub_solves = 2 ** cuts
            return h

        def succeeded(t: float, h_try: float, h: float) -> float:
            nonlocal cuts
            if observer:
                observer(t, self)
            if h < dt and cuts:  # grow back towards the nominal step after a success
                cuts = max(cuts - 1, 0)
                self._sub_solves = 2 ** cuts
                return grown(h, dt)
            return h

        budget = 100 * nominal_steps(t0, t_end, dt) + 10 * self.max_cuts
        try:
            t = march(t0, t_end, dt, self.step, failed, succeeded, budget, scale=dt)[0]
        except IntegrationError as err:
            self._end = (err.t, self._state())
            raise
        self._end = (t, self._state())
        return t
