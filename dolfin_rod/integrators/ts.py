"""PETSc TS on the same SemiDiscreteProblem: F(t, y, dy/dt) = 0 as an implicit DAE.

TS sees the residual through two callbacks (PETSc's implicit form):

    IFunction:  G(t, y, ydot)      = F(t, y, ydot; v) (assembly.block_system), with the
                                     Dirichlet rows replaced by y - g(t): the conditions
                                     are algebraic equations of the DAE;
    IJacobian:  dG/dy + a dG/dydot = sum_j [dF_i/dy_j + a dF_i/dydot_j], a = TS's ``shift``
                                     (a fem.Constant: the forms are compiled once).

Every model here is therefore a DAE.  The quasi-static Kelvin-Voigt-free torsion rod
(nu = mu = 0) is of index 1 (phi is algebraic: d/ds[alpha(phi_s - u_d)] = 0 is solvable
for phi given u_d), so the stiffly accurate / L-stable TS types (bdf, theta = 1, arkimex
l2, ...) apply to all models, and theta = 1/2, alpha apply with the usual caveat that
they do not damp the algebraic components (see docs/stability.md).

TS types (``ts_type`` string, parameter after a colon like TimeStepper's
"generalized_alpha:0.3"):

    bdf[:k]              BDF of order k = 1..6 (default 2), fixed step or adaptive
    theta[:th]           theta method, endpoint form (th = 1/2: Crank-Nicolson), default 1
    backward_euler       theta = 1
    crank_nicolson       theta = 1/2, endpoint form (trapezoidal rule)
    implicit_midpoint    theta = 1/2, midpoint form
    alpha[:rho_inf]      TSALPHA, Jansen-Whiting-Hulbert generalized-alpha (default 0.5)
    alpha2[:rho_inf]     TSALPHA2, Chung-Hulbert generalized-alpha for second-order
                         problems (problem.SecondOrderProblem, e.g.
                         TorsionModel.second_order_problem())
    arkimex[:type]       ARKIMEX treated as fully implicit DIRK (no explicit part), type
                         one of ARKIMEX_ORDERS (default l2, L-stable, 2nd order)

Step rejection: a SNES failure rejects the step and TS retries with dt scaled by
``ts_adapt_scale_solve_failed`` (0.25); ``max_rejections`` consecutive rejections of one
step end the run with IntegrationError, the accepted history staying with the observer
and the last accepted state in ``problem.fields``.  In fixed-step mode the step grows
back to the nominal dt (doubling) after a cut, like TimeStepper.  A stage solve SNES
reports as converged counts as a failure when its residual at the solution misses the
tolerances (fem/solvers.CheckedSNES: ksponly, a trusted small step), whatever the options.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Callable

import dolfinx.fem as fem
import numpy as np
from petsc4py import PETSc

from ..checks import TS_ATOL, TS_RTOL
from ..fem.problem import SecondOrderProblem, SemiDiscreteProblem
from ..fem.assembly import block_system
from ..fem.solvers import CheckedSNES, ForceScale, petsc_options
from .step_control import (IntegrationError, StepStats, check_run, clip_to_end, grown,
                       nominal_steps, reached)

# Design orders of the ARKIMEX tableaux (implicit part), PETSc's TSARKIMEX names.
# (ars122 is left out: PETSc refuses it without an explicit part, error 56.)
ARKIMEX_ORDERS = {"1bee": 1, "a2": 2, "l2": 2, "2c": 2, "2d": 2, "2e": 2, "prssp2": 2,
                  "3": 3, "bpr3": 3, "ars443": 3, "4": 4, "5": 5}
TS_TYPES = ("bdf[:order]", "theta[:theta]", "backward_euler", "crank_nicolson",
            "implicit_midpoint", "alpha[:rho_inf]", "alpha2[:rho_inf]", "arkimex[:type]")
_ids = itertools.count()
_REASONS = {v: k for k, v in vars(PETSc.TS.ConvergedReason).items() if isinstance(v, int)}


@dataclass(frozen=True)
class TSMethod:
    """A parsed ``ts_type``: PETSc type, its options and the design order."""

    name: str
    petsc_type: str
    order: int
    options: dict


def parse_ts_type(ts_type: str) -> TSMethod:
    """'bdf:3' -> TSMethod('bdf:3', 'bdf', 3, {...}); ValueError for unknown names."""
    if not isinstance(ts_type, str):
        raise ValueError(f"ts_type must be a string, got {ts_type!r}")
    name, _, arg = ts_type.partition(":")

    def number(kind, cast, low, high):
        try:
            value = cast(arg)
        except ValueError:
            raise ValueError(f"ts_type '{ts_type}': {kind} must be a number, got '{arg}'") from None
        if not low <= value <= high:
            raise ValueError(f"ts_type '{ts_type}': {kind} must be in [{low}, {high}]")
        return value

    if name == "bdf":
        k = number("order", int, 1, 6) if arg else 2
        return TSMethod(f"bdf:{k}", "bdf", k, {"ts_bdf_order": k})
    if name in ("theta", "backward_euler", "crank_nicolson", "implicit_midpoint") and (
            not arg or name == "theta"):
        theta = {"backward_euler": 1.0, "crank_nicolson": 0.5, "implicit_midpoint": 0.5}.get(
            name, number("theta", float, 0.5, 1.0) if arg else 1.0)
        endpoint = name != "implicit_midpoint"
        return TSMethod(name if name != "theta" else f"theta:{theta:g}", "theta",
                        2 if theta == 0.5 else 1,
                        {"ts_theta_theta": theta, "ts_theta_endpoint": endpoint})
    if name in ("alpha", "alpha2"):
        rho = number("rho_inf", float, 0.0, 1.0) if arg else 0.5
        return TSMethod(f"{name}:{rho:g}", name, 2, {"ts_alpha_radius": rho})
    if name == "arkimex":
        kind = arg or "l2"
        if kind not in ARKIMEX_ORDERS:
            raise ValueError(f"unknown ARKIMEX type '{kind}' (known: {', '.join(ARKIMEX_ORDERS)})")
        return TSMethod(f"arkimex:{kind}", "arkimex", ARKIMEX_ORDERS[kind],
                        {"ts_arkimex_type": kind, "ts_arkimex_fully_implicit": True})
    if name in ("euler", "rk", "ssp", "fe"):
        raise ValueError(f"ts_type '{ts_type}' is explicit and needs an RHS function; a "
                         "SemiDiscreteProblem is implicit (DAE): use TimeStepper("
                         "problem, 'explicit_euler') for an explicit scheme")
    raise ValueError(f"unknown ts_type '{ts_type}' (known: {', '.join(TS_TYPES)})")


class TSIntegrator:
    """Advance a SemiDiscreteProblem with PETSc TS.

    adaptive:  False: fixed nominal step dt (ts_adapt_type none);  True: TS's error
               control with ``rtol``, ``atol`` (ts_adapt_type basic), dt = first step.
    observer(t, integrator) is called at t0 and after every accepted step; the state is
    in ``problem.fields``, ``problem.rates`` holds the backward difference of the last
    accepted step (a first-order rate estimate, for diagnostics only).
    dt_min:    a step that had to be cut below dt_min ends the run with IntegrationError
               (default: fixed step dt 4^-max_rejections, adaptive: no floor).
    ``solver_options`` are SNES/KSP options, ``ts_options`` further TS options (both
    without prefix).
    """

    def __init__(self, problem: SemiDiscreteProblem, ts_type: str = "bdf", *,
                 adaptive: bool = False, rtol: float = TS_RTOL, atol: float = TS_ATOL,
                 solver_options: dict | None = None, ts_options: dict | None = None,
                 max_rejections: int = 10, dt_min: float | None = None):
        if getattr(problem, "lie_group", False):
            raise ValueError("a rod with rotation-vector unknowns (RodModel's default for "
                             "dynamic rods) is advanced by TimeStepper (generalized-alpha "
                             "on the rotation group); for PETSc TS build RodModel(..., "
                             "rotations='quaternion')")
        if problem.links:
            raise ValueError("PETSc TS does not hold the one-node links of a support on an "
                             "axis off the coordinate axes (end_slide): advance it with "
                             "TimeStepper (a per-step scheme)")
        self.method = parse_ts_type(ts_type)
        for name, value in (("rtol", rtol), ("atol", atol)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value}")
        if not (isinstance(max_rejections, int) and max_rejections >= 0):
            raise ValueError(f"max_rejections must be an integer >= 0, got {max_rejections!r}")
        solver_settings = petsc_options(problem.comm, solver_options)
        self.problem, self.adaptive, self.dt_min = problem, adaptive, dt_min
        self.max_rejections = max_rejections
        y, ydot = problem.fields, problem.rates
        mesh = y[0].function_space.mesh
        self.shift = fem.Constant(mesh, 1.0)

        # IJacobian = dF/dy + shift dF/d(ydot) (+ a_shift dF/d(yddot) for TSALPHA2),
        # compiled once with the shifts as Constants.
        self.second_order = self.method.petsc_type == "alpha2"
        if self.second_order != isinstance(problem, SecondOrderProblem):
            wanted = ("a SecondOrderProblem (e.g. TorsionModel.second_order_problem())"
                      if self.second_order else "a first-order SemiDiscreteProblem")
            raise ValueError(f"ts_type '{ts_type}' needs {wanted}")
        self.a_shift = fem.Constant(mesh, 0.0)
        groups = [y, ydot] + ([problem.accelerations] if self.second_order else [])
        terms = [(1.0, 0), (self.shift, 1)] + ([(self.a_shift, 2)] if self.second_order else [])
        self.system = block_system(problem.residual, groups, terms, problem.bcs)
        self.b, self.x, self.A = self.system.b, self.system.x, self.system.A
        self._x_prev = self.x.duplicate()
        self._create_ts(mesh.comm, {**solver_settings,
                                    "ts_adapt_type": "basic" if adaptive else "none",
                                    **self.method.options, **(ts_options or {})}, rtol, atol,
                        ForceScale(problem.force_scale, solver_options,
                                   static=not problem.inertia))
        self.stats = StepStats()
        self._observer = None
        self._stop = None
        self._t_accepted = None
        self._dt_nominal = None

    def _create_ts(self, comm, settings: dict, rtol: float, atol: float,
                   scale: ForceScale) -> None:
        """PETSc TS on the callbacks below, options under a private prefix."""
        self.ts = PETSc.TS().create(comm)
        self.prefix = f"dolfin_rod_ts_{next(_ids)}_"
        self.ts.setOptionsPrefix(self.prefix)
        self.ts.setProblemType(PETSc.TS.ProblemType.NONLINEAR)
        self.ts.setEquationType(PETSc.TS.EquationType.DAE_IMPLICIT_INDEX1)
        self.ts.setType(self.method.petsc_type)
        if self.second_order:
            self.ts.setI2Function(self._i2function, self.b)
            self.ts.setI2Jacobian(self._i2jacobian, self.A)
            self._v = self.x.duplicate()
        else:
            self.ts.setIFunction(self._ifunction, self.b)
            self.ts.setIJacobian(self._ijacobian, self.A)
        # the last step is clipped in _post_step (TS's MATCHSTEP trips on round-off)
        self.ts.setExactFinalTime(PETSc.TS.ExactFinalTime.STEPOVER)
        self.ts.setMaxSNESFailures(-1)            # every SNES failure: reject, cut, retry
        self.ts.setMaxStepRejections(self.max_rejections)
        self.ts.setErrorIfStepFails(False)
        self.ts.setTolerances(rtol=rtol, atol=atol)
        opts = PETSc.Options()
        self._option_keys = [self.prefix + k for k in settings]
        for k, v in settings.items():
            opts[self.prefix + k] = v
        self.ts.setFromOptions()
        # after the options: theirs too; the force scale at each stage solve's time
        self.snes_check = CheckedSNES(self.ts.getSNES(), scale)
        self.ts.setMonitor(self._monitor)
        self.ts.setPostStep(self._post_step)

    # -- the DAE ----------------------------------------------------------------------
    def _set_time(self, t: float, x, xdot) -> None:
        self.system.set(0, x)
        self.system.set(1, xdot)
        self.problem.set_loads(t)
        self.problem.set_bcs(t)

    def _ifunction(self, ts, t, x, xdot, b):
        self._set_time(t, x, xdot)
        self.system.residual(x, b)

    def _i2function(self, ts, t, x, xdot, xddot, b):
        self.system.set(2, xddot)
        self._ifunction(ts, t, x, xdot, b)

    def _i2jacobian(self, ts, t, x, xdot, xddot, v_shift, a_shift, A, P):
        self.system.set(2, xddot)
        self.a_shift.value = a_shift
        self._ijacobian(ts, t, x, xdot, v_shift, A, P)

    def _ijacobian(self, ts, t, x, xdot, shift, A, P):
        self._set_time(t, x, xdot)
        self.shift.value = shift
        self.system.jacobian(A)

    # -- accepted steps ---------------------------------------------------------------
    def _monitor(self, ts, step, t, x):
        self.system.set(0, x)
        h = t - self._t_accepted if self._t_accepted is not None else 0.0
        if self.second_order:  # TSALPHA2 carries the rate itself
            self.system.set(1, ts.getSolution2()[1])
            self._after_step(ts)
        elif h > 0:  # backward-difference rate of the accepted step
            rate = x.copy()
            rate.axpy(-1.0, self._x_prev)
            rate.scale(1.0 / h)
            self.system.set(1, rate)
            rate.destroy()
            self._after_step(ts)
        x.copy(self._x_prev)
        self._t_accepted = t
        if step > 0:
            self.stats.steps += 1
        if self._observer:
            self._observer(t, self)

    def _after_step(self, ts) -> None:
        """problem.after_step (a rod: its checks of the accepted state); an
        IntegrationError it raises stops TS and is raised by run (not through PETSc's
        callback error)."""
        if self._stop is not None:
            return
        try:
            self.problem.after_step()
        except IntegrationError as err:
            self._stop = err              # TS stops after the step under way (_post_step)

    def _post_step(self, ts):
        if self._stop is not None:
            ts.setConvergedReason(PETSc.TS.ConvergedReason.DIVERGED_STEP_REJECTED)
            return
        dt, t = ts.getTimeStep(), ts.getTime()
        if not self.adaptive and dt < self._dt_nominal:  # grow back after a cut
            dt = grown(dt, self._dt_nominal)
        if reached(t, self._t_end, self._dt_nominal):
            ts.setConvergedReason(PETSc.TS.ConvergedReason.CONVERGED_TIME)
        elif clip_to_end(t, self._t_end, dt) != dt:
            dt = self._t_end - t
        elif self._dt_floor > 0 and dt < self._dt_floor:
            ts.setConvergedReason(PETSc.TS.ConvergedReason.DIVERGED_STEP_REJECTED)
        ts.setTimeStep(dt)

    # -- driver -----------------------------------------------------------------------
    def run(self, t0: float, t_end: float, dt: float,
            observer: Callable[[float, "TSIntegrator"], None] | None = None) -> float:
        """Integrate from t0 to t_end (dt: the fixed step, or the first adaptive one).

        Returns the final time; raises IntegrationError when a step is rejected
        ``max_rejections`` times in a row (state: the last accepted step).
        """
        check_run(t0, t_end, dt, self.problem, adaptive=self.adaptive)
        self._observer, self._t_accepted, self._dt_nominal = observer, None, dt
        self._t_end, self.snes_check.failure = t_end, None
        # smallest accepted step before giving up: dt_min, else (fixed step) dt 4^-rejections
        self._dt_floor = (self.dt_min if self.dt_min is not None else
                          0.0 if self.adaptive else dt * 0.25 ** self.max_rejections)
        # initial rates: whatever the problem holds (used only by diagnostics at t0)
        self.system.get(0, self.x)
        if self.second_order:  # initial velocity: the problem's rates
            self.system.get(1, self._v)
            self.ts.setSolution2(self.x, self._v)
        self.ts.setTime(t0)
        self.ts.setTimeStep(min(dt, t_end - t0))
        self.ts.setStepNumber(0)
        self.ts.setMaxTime(t_end)
        self.ts.setConvergedReason(PETSc.TS.ConvergedReason.CONVERGED_ITERATING)
        self.ts.setMaxSteps(max(10 * nominal_steps(t0, t_end, dt),
                                10**6 if self.adaptive else 0))
        self._stop = None
        self.ts.solve(self.x)
        if self._stop is not None:
            raise self._stop
        reason = self.ts.getConvergedReason()
        self.stats.rejected = self.ts.getStepRejections()
        self.stats.snes_failures = self.ts.getSNESFailures()
        self.stats.newton_iterations = self.ts.getSNESIterations()
        t = self._t_accepted
        if reason < 0 or not reached(t, t_end, dt):
            self.system.set(0, self._x_prev)
            raise IntegrationError(
                f"TS {self.method.name} stopped at t = {t:.6g} ({_REASONS.get(reason, reason)}"
                f", {self.stats.rejected} rejected steps, last dt = {self.ts.getTimeStep():.3g}"
                + (f"; last SNES failure: {self.snes_check.failure}" if self.snes_check.failure
                   else "") + ")", t)
        return t

    def __del__(self):
        try:
            opts = PETSc.Options()
            for k in self._option_keys:
                opts.delValue(k)
        except Exception:
            pass
