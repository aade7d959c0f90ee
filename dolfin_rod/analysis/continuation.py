"""Newton on an equilibrium path with the load as an unknown (issue 27 items 2 and 6).

The static equilibria of a rod (rates zero, natural strains frozen: the residual whose
tangent is TangentStiffness's K) at a load parameter lambda, F(y, lambda) = 0, with
lambda the time of the scene's load histories and prescribed end motions.  A scalar
constraint c(y, lambda) = 0 (a prescribed amplitude of a mode, an arc length) closes
the system; each Newton iteration solves the bordered system by block elimination,

    K a = -F,   K b = -F_lambda,   dlambda = -(c + c_y . a) / (c_lambda + c_y . b),
    dy = a + dlambda b,

two solves with one LU of K (MUMPS: K may be indefinite on an unstable branch) and
F_lambda by a difference in lambda (the loads and end motions at lambda + delta).
The bordered matrix is regular where the path is a regular curve, also at a limit
point (K singular, F_lambda not in its range) and next to a bifurcation once c picks
the branch (Keller 1977; Crisfield, Non-linear Finite Element Analysis of Solids and
Structures, vol. 1, sec. 9.3).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from petsc4py import PETSc

from ..fem.solvers import SolverError

__all__ = ["PathNewton", "Constraint", "ArcLength"]

# (c, c_y, c_lambda) of the state vector y and lambda
Constraint = Callable[[PETSc.Vec, float], tuple[float, PETSc.Vec | None, float]]
DELTA = 1e-7        # lambda's difference step, relative to max(1, |lambda|)
DESIRED_ITERATIONS = 4
MAX_TURN = 0.5      # rad: a step's secant against the last tangent (in the psi-weighted norm)


class PathNewton:
    """Newton on F(y, lambda) = 0, c(y, lambda) = 0 for the unknowns of a
    TangentStiffness (``solve(lam, constraint)`` from the current state)."""

    def __init__(self, tangent, max_it: int = 30, rtol: float = 1e-9):
        self.tangent, self.system = tangent, tangent.system
        self.problem = tangent.model.problem
        self.max_it, self.rtol = max_it, rtol
        self.scale = self.problem.configuration_norm() or 1.0
        self.y = self.system.x.duplicate()
        self._F, self._F_shift = self.system.b.duplicate(), self.system.b.duplicate()
        self.ksp = PETSc.KSP().create(self.y.getComm())
        self.ksp.setType("preonly")
        pc = self.ksp.getPC()
        pc.setType("lu")
        pc.setFactorSolverType("mumps")
        self.iterations = 0

    def state(self) -> PETSc.Vec:
        """The current unknowns as a vector (a copy)."""
        self.system.get(0, self.y)
        return self.y.copy()

    def set_parameter(self, lam: float) -> None:
        self.problem.set_loads(lam)
        self.problem.set_bcs(lam)

    def residual(self, y: PETSc.Vec, lam: float, out: PETSc.Vec) -> None:
        """F(y, lambda) into out (Dirichlet rows: y - g(lambda))."""
        self.set_parameter(lam)
        self.system.set(0, y)
        self.system.residual(y, out)

    def load_derivative(self, y: PETSc.Vec, lam: float) -> PETSc.Vec:
        """F_lambda at (y, lambda) by a forward difference (exact for loads linear in
        lambda, a ramp's)."""
        delta = DELTA * max(1.0, abs(lam))
        derivative = self.system.b.duplicate()
        self.residual(y, lam + delta, derivative)
        self.residual(y, lam, self._F)
        derivative.axpy(-1.0, self._F)
        derivative.scale(1.0 / delta)
        return derivative

    def solve(self, lam: float, constraint: Constraint) -> float:
        """Newton from the current state and lambda; the fields then hold the solution
        (not committed) and its lambda is returned.  SolverError if it does not converge
        in max_it iterations: |F| <= rtol (|F_lambda| + |F_0|) and |c| <= rtol scale, or
        (a residual at its round-off floor: stiff axial terms on fine meshes) the last
        update below rtol times the configuration's norm and |dlambda| <= rtol (1 +
        |lambda|)."""
        y = self.state()
        a, b = y.duplicate(), y.duplicate()
        self.iterations = 0
        reference, moved = None, np.inf
        for it in range(self.max_it + 1):
            F_lam = self.load_derivative(y, lam)       # (leaves F(y, lambda) in _F)
            self.system.jacobian(self.system.A)
            c, c_y, c_lam = constraint(y, lam)
            norm = self._F.norm()
            reference = reference or norm + F_lam.norm()
            if (norm <= self.rtol * reference or moved <= self.rtol) \
                    and abs(c) <= self.rtol * (1.0 + abs(lam)):
                self.iterations = it
                self.system.set(0, y)
                return lam
            self.ksp.setOperators(self.system.A)
            self._F.scale(-1.0)
            self.ksp.solve(self._F, a)
            F_lam.scale(-1.0)
            self.ksp.solve(F_lam, b)
            c_y_a = c_y.dot(a) if c_y is not None else 0.0
            c_y_b = c_y.dot(b) if c_y is not None else 0.0
            step = -(c + c_y_a) / (c_lam + c_y_b)
            if not np.isfinite(step) or not np.isfinite(a.norm()):
                break
            a.axpy(step, b)
            y.axpy(1.0, a)
            lam += step
            moved = max(a.norm() / self.scale, abs(step) / (1.0 + abs(lam)))
        self.system.set(0, y)
        raise SolverError("path Newton: not converged", self.max_it)


class ArcLength:
    """Riks' arc-length continuation of the static equilibria F(y, lambda) = 0 of a rod
    (natural strains frozen), lambda the time of its load histories (a ramp of duration
    1: the load factor), through limit points: each step solves with the normal-plane
    constraint (Riks 1979, Ramm 1981; Crisfield, vol. 1, sec. 9.3)

        (y - y_p) . t_y + psi^2 (lambda - lambda_p) t_lambda = 0,

    (y_p, lambda_p) = (y_k, lambda_k) + ds t the predictor along the unit tangent t (the
    secant of the last step, the first from K t_y = -F_lambda), psi = ``load_scale`` the
    weight of lambda against the unknowns' Euclidean norm.  After each step the rod's
    rotation increments are committed (its stored rotations).  The step ds follows
    Newton's iterations (x sqrt(DESIRED_ITERATIONS / iterations), within
    [ds_min, ds_max]); a failed step is halved.  ``run(lam_end)``: steps until lambda
    >= lam_end; ``points``: (lambda, observer value) after each step."""

    def __init__(self, model, ds: float, load_scale: float = 1.0, ds_max: float | None = None,
                 observe=None, max_steps: int = 500):
        from .stability import TangentStiffness
        self.model, self.problem = model, model.problem
        self.path = PathNewton(TangentStiffness(model))
        self.ds, self.ds_min, self.ds_max = ds, ds * 1e-4, ds_max or ds
        self.psi, self.observe, self.max_steps = load_scale, observe, max_steps
        self.points: list[tuple[float, float]] = []

    def run(self, lam0: float, lam_end: float, after_step=None) -> float:
        """From the equilibrium at lam0 (the model's state) until lambda >= lam_end, at
        most max_steps steps, ``after_step(lambda)`` after each; the last lambda.
        SolverError if a step fails below ds_min."""
        lam = lam0
        self.path.set_parameter(lam)
        tangent, d_lam = self._first_tangent(lam)
        self._record(lam)
        for _ in range(self.max_steps):
            if lam >= lam_end:
                break
            lam, tangent, d_lam = self._step(lam, tangent, d_lam)
            if after_step is not None:
                after_step(lam)
        return lam

    def _first_tangent(self, lam: float):
        """The unit tangent at the start, towards increasing lambda: K t_y = -F_lambda."""
        y = self.path.state()
        F_lam = self.path.load_derivative(y, lam)
        self.path.system.jacobian(self.path.system.A)
        self.path.ksp.setOperators(self.path.system.A)
        t_y = y.duplicate()
        F_lam.scale(-1.0)
        self.path.ksp.solve(F_lam, t_y)
        return self._unit(t_y, 1.0)

    def _unit(self, t_y, t_lam: float):
        norm = np.sqrt(t_y.dot(t_y) + (self.psi * t_lam) ** 2)
        t_y.scale(1.0 / norm)
        return t_y, t_lam / norm

    def _step(self, lam: float, tangent, d_lam: float):
        """One step of length ds along the path: halved while Newton fails or the step
        turns by more than MAX_TURN from the tangent (it jumped to another part of the
        path)."""
        start = self.path.state()
        while True:
            predictor = start.copy()
            predictor.axpy(self.ds, tangent)
            lam_p = lam + self.ds * d_lam
            self.path.system.set(0, predictor)

            def normal_plane(y, lam_, predictor=predictor, lam_p=lam_p):
                diff = y.copy()
                diff.axpy(-1.0, predictor)
                return (diff.dot(tangent) + self.psi ** 2 * (lam_ - lam_p) * d_lam,
                        tangent, self.psi ** 2 * d_lam)

            try:
                new = self.path.solve(lam_p, normal_plane)
                increment = self.path.state()
                increment.axpy(-1.0, start)   # rotation increments: theta (committed: 0)
                secant = self._unit(increment, new - lam)
                if secant[0].dot(tangent) + self.psi ** 2 * secant[1] * d_lam \
                        < np.cos(MAX_TURN):
                    raise SolverError(f"the step turned by more than {MAX_TURN:g} rad", 0)
                break
            except SolverError:
                self.path.system.set(0, start)
                self.ds *= 0.5
                if self.ds < self.ds_min:
                    raise
        self.problem.after_step()          # the rod's stored rotations take them
        self.path.set_parameter(new)
        self._record(new)
        growth = np.sqrt(DESIRED_ITERATIONS / max(self.path.iterations, 1))
        self.ds = float(np.clip(self.ds * growth, self.ds_min, self.ds_max))
        return (new, *secant)

    def _record(self, lam: float) -> None:
        self.points.append((lam, self.observe(lam) if self.observe else 0.0))
