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

from ..solvers import BlockSNES


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
    increments into the stored rotations (and resets them to 0)."""

    def __init__(self, problem, rho_inf: float = 0.8, solver_options=None):
        self.problem = problem
        self.am, self.af, self.gamma, self.beta = alpha_parameters(rho_inf)
        mesh = problem.fields[0].function_space.mesh
        self.dt = fem.Constant(mesh, 1.0)
        self.order = problem.time_orders
        y, r, acc = problem.fields, problem.rates, problem.accelerations
        self.y_n = [_copy(f, "n") for f in y]
        self.v_n = [_copy(f, "rate_n") for f in r]
        self.acc_n = [None if a is None else _copy(a, "acc_n") for a in acc]
        # algorithmic accelerations a (second order) or rates b (first order)
        self.alg_n = [_copy(f, "alg_n") for f in r]
        mapping = {}
        for i, f in enumerate(y):
            new_r, new_a = self._ufl_update(i, f - self.y_n[i])
            mapping[r[i]] = new_r
            if acc[i] is not None:
                mapping[acc[i]] = new_a
        F = [ufl.replace(Fi, mapping) for Fi in problem.residual]
        self.solver = BlockSNES(F, y, problem.bcs, solver_options)
        self.iterations = 0
        self.steps = 0
        self._started = False
        self._dt_last = None

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

    def initial_accelerations(self, t0: float, bcs) -> None:
        """Solve the residual at t0 for the accelerations (second order) and rates (first
        order) with the state fixed; bcs: homogeneous conditions on those spaces."""
        p = self.problem
        unknown = [a if a is not None else r for a, r in zip(p.accelerations, p.rates)]
        p.set_loads(t0)
        BlockSNES(p.residual, unknown, bcs).solve()
        for i, a in enumerate(unknown):
            self.alg_n[i].x.array[:] = a.x.array
        self._started = True

    def step(self, t: float, h: float) -> int:
        p = self.problem
        if not self._started:
            raise RuntimeError("call initial_accelerations(t0, bcs) first")
        self.dt.value = h
        for i, f in enumerate(p.fields):
            self.y_n[i].x.array[:] = f.x.array
            self.v_n[i].x.array[:] = p.rates[i].x.array
            if p.accelerations[i] is not None:
                self.acc_n[i].x.array[:] = p.accelerations[i].x.array
            # predictor: algorithmic acceleration / rate kept
            alg, vn = self.alg_n[i].x.array, self.v_n[i].x.array
            if self.order[i] == 2:
                f.x.array[:] += h * vn + 0.5 * h * h * alg
            else:
                f.x.array[:] += h * alg
        p.set_loads(t + h)
        p.set_bcs(t + h)
        fresh, self._dt_last = h != self._dt_last, h
        its = self.solver.solve(fresh_jacobian=fresh)
        for i, f in enumerate(p.fields):
            alg_new, v_new, acc_new = self._np_update(i, f.x.array - self.y_n[i].x.array, h)
            self.alg_n[i].x.array[:] = alg_new
            p.rates[i].x.array[:] = v_new
            if acc_new is not None:
                p.accelerations[i].x.array[:] = acc_new
        p.after_step()
        self.iterations += its
        self.steps += 1
        return its
