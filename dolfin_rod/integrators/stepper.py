"""Per-step time integration: a scheme turns F(t, y, dy/dt) into a step residual that
BlockSNES solves.  Step cutting recovers from Newton failures; an unrecoverable failure
raises IntegrationError and leaves every accepted step with the observer.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Callable

import dolfinx.fem as fem
import numpy as np
import ufl

from ..problem import SemiDiscreteProblem
from ..solvers import BlockSNES, SolverError
from .schemes import Scheme, get_scheme


class IntegrationError(RuntimeError):
    """The run stopped early; ``t`` is the last accepted time (its state is kept)."""

    def __init__(self, message: str, t: float):
        super().__init__(message)
        self.t = t


def _copy(f: fem.Function) -> fem.Function:
    g = fem.Function(f.function_space, name=f"{f.name}_old")
    g.x.array[:] = f.x.array
    return g


class _StepResidual:
    """The compiled step residual of one scheme (dt, loads and stage times are Constants)."""

    def __init__(self, problem: SemiDiscreteProblem, scheme: Scheme, history, dt, options):
        self.problem, self.scheme = problem, scheme
        y, ydot = problem.fields, problem.rates
        y_n, y_nm1, ydot_n = history
        mesh = y[0].function_space.mesh
        self.stage_loads = []
        F = [0] * len(y)
        for st in scheme.stages:
            mapping = {}
            for i in range(len(y)):
                mapping[y[i]] = st.a[0] * y[i] + st.a[1] * y_n[i] + st.a[2] * y_nm1[i]
                mapping[ydot[i]] = ((st.b[0] * y[i] + st.b[1] * y_n[i] + st.b[2] * y_nm1[i]) / dt
                                    + st.g * ydot_n[i])
            loads = []
            for load in problem.loads:
                c = fem.Constant(mesh, np.array(load.constant.value, dtype=float))
                mapping[load.constant] = c
                loads.append((c, load))
            self.stage_loads.append((st.c, loads))
            F = [Fi + st.w * ufl.replace(Ri, mapping) for Fi, Ri in zip(F, problem.residual)]
        self.solver = BlockSNES(F, y, problem.bcs, options)
        self._dt_last = None

    def solve(self, t_n: float, dt: float) -> int:
        for c, loads in self.stage_loads:
            for const, load in loads:
                const.value[...] = load.at(t_n + c * dt)
        self.problem.set_bcs(t_n + dt)
        fresh, self._dt_last = dt != self._dt_last, dt  # a reused Jacobian holds the old dt
        return self.solver.solve(fresh_jacobian=fresh)


@dataclass
class StepStats:
    steps: int = 0
    newton_iterations: int = 0
    rejected: int = 0


class TimeStepper:
    """Advance a SemiDiscreteProblem with a per-step scheme.

    observer(t, stepper) is called at t0 and after every accepted step; the state is in
    ``problem.fields`` and the rate estimate at t in ``problem.rates``.
    predictor:  Newton's initial guess, "linear" y_n + dt dy/dt_n (an O(dt^2) guess:
                about one Newton iteration fewer per step on smooth dynamics) or
                "constant" y_n.
    """

    PREDICTORS = ("linear", "constant")

    def __init__(self, problem: SemiDiscreteProblem, scheme: str = "backward_euler",
                 solver_options: dict | None = None, max_cuts: int = 6,
                 predictor: str = "linear"):
        if predictor not in self.PREDICTORS:
            raise ValueError(f"predictor must be one of {self.PREDICTORS}, got {predictor!r}")
        self.predictor = predictor
        self.problem = problem
        self.scheme = get_scheme(scheme)
        self.options = solver_options
        self.max_cuts = max_cuts
        self.y_n = [_copy(f) for f in problem.fields]
        self.y_nm1 = [_copy(f) for f in problem.fields]
        self.ydot_n = [_copy(f) for f in problem.rates]
        self.dt = fem.Constant(problem.fields[0].function_space.mesh, 1.0)
        self._residuals: dict[str, _StepResidual] = {}
        self.stats = StepStats()
        self._history_ok = False  # y_{n-1}, ydot_n valid for the current dt (else: startup)

    def _residual(self, scheme: Scheme) -> _StepResidual:
        if scheme.name not in self._residuals:
            history = (self.y_n, self.y_nm1, self.ydot_n)
            self._residuals[scheme.name] = _StepResidual(
                self.problem, scheme, history, self.dt, self.options)
        return self._residuals[scheme.name]

    def _update_rates(self, scheme: Scheme, dt: float) -> None:
        r0, r1, r2, rg = scheme.rate
        for f, fn, fnm1, rate, rate_n in zip(self.problem.fields, self.y_n, self.y_nm1,
                                              self.problem.rates, self.ydot_n):
            rate.x.array[:] = ((r0 * f.x.array + r1 * fn.x.array + r2 * fnm1.x.array) / dt
                               + rg * rate_n.x.array)

    def step(self, t: float, dt: float) -> None:
        """One step from t (state in problem.fields) to t + dt; raises SolverError."""
        scheme = self.scheme
        if scheme.startup and not self._history_ok:
            scheme = get_scheme(scheme.startup)
        for fn, f, rn, r in zip(self.y_n, self.problem.fields, self.ydot_n, self.problem.rates):
            fn.x.array[:] = f.x.array
            rn.x.array[:] = r.x.array
            if self.predictor == "linear":
                f.x.array[:] += dt * r.x.array
        self.dt.value = dt
        try:
            its = self._residual(scheme).solve(t, dt)
        except SolverError:
            for fn, f in zip(self.y_n, self.problem.fields):
                f.x.array[:] = fn.x.array
            raise
        if not all(np.isfinite(f.x.array).all() for f in self.problem.fields):
            for fn, f in zip(self.y_n, self.problem.fields):
                f.x.array[:] = fn.x.array
            raise SolverError("non-finite solution", its)
        self._update_rates(scheme, dt)
        for fnm1, fn in zip(self.y_nm1, self.y_n):
            fnm1.x.array[:] = fn.x.array
        self._history_ok = True
        self.stats.steps += 1
        self.stats.newton_iterations += its

    def run(self, t0: float, t_end: float, dt: float,
            observer: Callable[[float, "TimeStepper"], None] | None = None) -> float:
        """Integrate from t0 to t_end with nominal step dt, cutting steps on failure."""
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        if not t_end > t0:
            raise ValueError(f"t_end must be > t0 = {t0}, got {t_end}")
        if observer:
            observer(t0, self)
        t, h, cuts = t0, dt, 0
        n_total = math.ceil((t_end - t0) / dt - 1e-9)
        for _ in range(100 * n_total + 10 * self.max_cuts):
            if t_end - t <= 1e-9 * dt:  # round-off from summing steps
                return t
            h_try = t_end - t if t_end - t < h * (1 + 1e-9) else h
            try:
                self.step(t, h_try)
            except SolverError as err:
                cuts += 1
                self.stats.rejected += 1
                if cuts > self.max_cuts:
                    raise IntegrationError(
                        f"time step failed at t = {t:.6g} after {self.max_cuts} step cuts "
                        f"(last dt = {h_try:.3g}): {err}", t) from err
                h = h_try / 2
                if self.scheme.startup:
                    warnings.warn(f"step at t = {t:.6g} cut to dt = {h:.3g} ({err}); "
                                  f"{self.scheme.name} restarts with {self.scheme.startup}, "
                                  "which is first-order accurate", RuntimeWarning,
                                  stacklevel=2)
                self._history_ok = False
                continue
            t = t_end if h_try == t_end - t else t + h_try
            if observer:
                observer(t, self)
            if h < dt and cuts:  # grow back towards the nominal step after a success
                h = min(2 * h, dt)
                self._history_ok = False
                cuts = max(cuts - 1, 0)
        raise IntegrationError(f"step budget exhausted at t = {t:.6g}", t)
