"""Linearised buckling about the current (pre-loaded) equilibrium of a quasi-static rod.

Along a load path the equilibrium state y(t) solves R(y, t) = 0, with the loads and
prescribed end motions of time t.  About the current state the tangent stiffness grows
along the path as K + tau K', the classical linearised buckling problem (the
pre-buckling deformation's change of the geometry neglected):

    K' = K_sigma(m', n') + dK/dt,   m', n' = dm/dy [y'], dn/dy [y'],   K y' = -dR/dt

(a system with hinges adds sum_i F'_i d^2 Phi_i/dz^2: the rate along y' of the forces
F_i the hinges carry, their "stresses" in P^T K P + sum_i F_i d^2 Phi_i/dz^2 (the exact
tangent through a hinge, fem/multipoint.py), times the maps' second derivatives at the
state; the loads' rate at the hinge is in dK/dt)

K_sigma(m', n') = d^2/dy^2 int (m' . u(y) + n' . v(y)) ds is the geometric (initial
stress) stiffness of the stress rates m', n' along the path's tangent y' (Dirichlet
rows: the prescribed motion's rate), at the current geometry; dK/dt that of follower
loads.  The critical points are the eigenpairs of K phi = tau (-K') phi
(analysis/eigen.py; symmetric parts): the critical time t + tau and the load factor
(t + tau) / t, the multiple of the current loads and motions when they grow in
proportion to t (ramps from t = 0).

How each rate is formed.  m', n' (and the hinges' F'_i): exact, UFL's derivative of
the stresses along y' (the carried forces' J P y'); before, a central difference at
y +- delta y' divided the stresses' round-off (the axial and shear stiffness 1e5 times a
strain's cancellation) by delta: a column and the same column as two welded rods were
1.1e-8 apart at delta = 1e-4 t (8.5e-8 at 1e-5), now 4e-12.  dR/dt: a second-order
backward difference in time (_backward_rate), one-sided so that a ramp that ends at t
counts with its rate before t, exact for histories quadratic over [t - 2 delta, t];
the internal forces, which do not change with t, cancel exactly in it.  dK/dt: K is
affine in the loads' values, so the histories' rates (the same difference) give it
exactly from K at c + t c' (_load_stiffness_rate).  delta = RELATIVE_STEP t = 1e-5 t
balances the difference's truncation, (delta^2 / 3) f'''/f' (6.7e-7, 6.7e-9, 8e-11 of
a cubic ramp's critical time at delta = 1e-3, 1e-4, 1e-5 t), against its round-off,
eps / delta (9e-12 on a column, 1.5e-10 on a follower-loaded arch at 1e-5 t).

Only K_sigma, not the full derivative of K along the path: on rotation vectors the
unknowns are increments in a basis that turns with the rod, and the difference of two
tangents along a path that turns it (a twist) holds the basis's turn, of the size of
the shear stiffness (measured: Greenhill's critical twist off by a factor 100).  For a
straight column both are the same.  The quaternion form: K bordered by the gauge
multiplier (zero rows of K'); the strains depend on q/|q| only (u, v are invariant
under q -> c(s) q), so the energy's gradient along q vanishes and the Hessians in q,
restricted to the directions |q| = 1 leaves free, are those in rotation increments; the
gauge's multiplier is 0 at every equilibrium, its rate too.  Rod systems with joints:
P^T K P and P^T K' P (fem/multipoint.py).  Not for constrained rods (their multipliers
are stresses whose rates K' would need).
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx.fem as fem
import numpy as np
import ufl
from petsc4py import PETSc
from ufl.algorithms import expand_derivatives

from ..fem.assembly import block_system
from ..fem.compat import interpolation_points
from ..fem.multipoint import ConstrainedSystem
from .eigen import eigenpairs
from .stability import TangentStiffness, at_rest_map, symmetric_part

__all__ = ["BucklingModes", "buckling_modes"]

RELATIVE_STEP = 1e-5       # delta / t of the rates in time (module docstring)


@dataclass
class BucklingModes:
    """``times``: the critical times t + tau of the linearised path, nearest t first;
    ``load_factors``: (t + tau) / t; ``shapes``: per mode {block: nodal values} of the
    displacement and rotation blocks (the mode's largest displacement 1, rotations
    alongside); ``residuals``: the eigen-solve's relative residuals."""

    t: float
    times: np.ndarray
    load_factors: np.ndarray
    shapes: list[dict[str, np.ndarray]]
    residuals: np.ndarray


def buckling_modes(model, t: float, count: int = 4) -> BucklingModes:
    """The ``count`` critical points of the linearised load path of a quasi-static
    RodModel (or RodSystem) nearest its current equilibrium at time t (> 0: the state reached under
    time t's loads).  Raises ValueError for a dynamic rod, a rod system with joints, t
    <= 0, a constrained rod (material.constraint), or loads and motions that do not
    change at t."""
    if model.dynamic:
        raise ValueError("buckling: a quasi-static rod (density = 0); for a dynamic one, "
                         "the vibration modes (analysis/vibration.py)")
    if not t > 0:
        raise ValueError(f"buckling: t > 0 (the loads of time t are scaled), got {t!r}")
    tangent = TangentStiffness(model)
    system = tangent.system
    state = system.x.copy()
    system.get(0, state)
    try:
        K, dK = _pencil(tangent, state, t, RELATIVE_STEP * t)
        dK.scale(-1.0)
        pairs = eigenpairs(K, dK, count, target=0.0, kind="symmetric_indefinite")
        shapes = tangent.mode_shapes(pairs.vectors)
    finally:
        system.set(0, state)
        model.problem.set_loads(t)
        model.problem.set_bcs(t)
    times = t + pairs.values
    return BucklingModes(t, times, times / t, shapes, pairs.residuals)


def _pencil(tangent: TangentStiffness, state: PETSc.Vec, t: float,
            delta: float) -> tuple[PETSc.Mat, PETSc.Mat]:
    """K at the state and the load's derivative K' (module docstring)."""
    system, problem = tangent.system, tangent.model.problem
    rate = _path_rate(tangent, state, t, delta)
    if not rate.norm() > 0:
        raise ValueError(f"buckling: the loads and prescribed motions do not change at "
                         f"t = {t:g} (nothing to scale: ramp them)")
    stress = _StressStiffness(tangent)
    try:
        tangent.set_direction(rate)
        stress.take_direction()
        system.set(0, state)
        stress.set_rates()
        dK = stress.matrix()
        if isinstance(system, ConstrainedSystem) and system.curved:
            carried = system.carried_rate(state, rate)       # F' of the hinges
            system.add_map_forces(dK, system.curved, carried)
            carried.destroy()
        K = tangent.matrix(t)
        dK.axpy(1.0, _load_stiffness_rate(tangent, K, t, delta))
    finally:
        system.set(0, state)
        problem.set_loads(t)
    return K, dK


class _StressStiffness:
    """K_sigma(m', n') of a rod (module docstring): m', n' DG0 (the one-point rule's
    cell midpoints), the derivatives of m, n along a direction of the fields
    (``take_direction``), exact (UFL's derivative)."""

    def __init__(self, tangent: TangentStiffness):
        model = tangent.model
        if "constraint_multiplier" in tangent.names:
            raise ValueError("buckling: a rod without constraints (no material.constraint)")
        S = fem.functionspace(model.mesh, ("DG", 0, (3,)))
        at_rest = at_rest_map(model)
        points = interpolation_points(S)
        self.model, self.names = model, tangent.names
        self.direction = {n: fem.Function(model.f[n].function_space) for n in tangent.names}
        self.stress_rates = [fem.Expression(expand_derivatives(sum(
            ufl.derivative(ufl.replace(f, at_rest), model.f[n], self.direction[n])
            for n in tangent.names)), points) for f in (model.m, model.n)]
        self.rates = [fem.Function(S), fem.Function(S)]
        work = sum(ufl.inner(rate, strain) for rate, strain in
                   zip(self.rates, (model.u, model.v))) * model.dx_r
        fields = [model.f[n] for n in tangent.names]
        forms = [ufl.derivative(work, f, model.t[n]) for f, n in zip(fields, tangent.names)]
        bcs = [bc for n in tangent.names for bc in model.bcs_of(n)]
        self.system = block_system(forms, [fields], bcs=bcs)
        self.fixed = tangent.fixed
        self.joints = tangent.system.P if isinstance(tangent.system, ConstrainedSystem) \
            else None

    def take_direction(self) -> None:
        """The direction: the values in the model's fields (TangentStiffness.set_direction)."""
        for n in self.names:
            self.direction[n].x.array[:] = self.model.f[n].x.array

    def set_rates(self) -> None:
        """m', n' at the state in the fields along the direction."""
        for rate, expression in zip(self.rates, self.stress_rates):
            rate.interpolate(expression)

    def matrix(self) -> PETSc.Mat:
        """K_sigma, symmetric part, Dirichlet rows and columns zero."""
        system = self.system
        system.get(0, system.x)                  # the state (its forms read their own copy)
        system.set(0, system.x)
        system.jacobian(system.A)
        A = system.A if self.joints is None else system.A.PtAP(self.joints)
        return symmetric_part(A, self.fixed, 0.0)


def _load_stiffness_rate(tangent: TangentStiffness, K: PETSc.Mat, t: float,
                         delta: float) -> PETSc.Mat:
    """dK/dt at the state (follower loads; 0 for dead ones), K the matrix at time t's
    loads.  K is affine in the loads' values c (each load a Constant: its history's
    value times a fixed vector, directors or profile), so dK/dt = (K(c + t c') - K(c)) / t
    exactly, with c' the histories' rates (_backward_rate).  The two matrices differ by
    t c', not by delta c': their common part (the elastic stiffness) cancels with a
    round-off t / delta times smaller than in (K(t) - K(t - delta)) / delta (measured
    on the follower-loaded arch of tests/test_buckling.py, whose shear stiffness 1e6
    sits beside loads of 8: 4.5e-7 of the critical time at delta = 1e-4 t)."""
    for load in tangent.model.problem.loads:
        load.constant.value[...] = load.at(t) + t * _backward_rate(load.at, t, delta)
    ahead = tangent.matrix(None)
    ahead.axpy(-1.0, K)
    ahead.scale(1.0 / t)
    return ahead


def _backward_rate(value, t: float, delta: float):
    """The derivative at t of ``value(time)`` (numbers, or a PETSc Vec at the same
    state), (3 f(t) - 4 f(t - delta) + f(t - 2 delta)) / (2 delta): exact for histories
    quadratic on [t - 2 delta, t] and one-sided, so that a ramp ending at t counts with
    its rate before t.  The differences of neighbours come first: what does not change
    with time (the internal forces) cancels exactly there."""
    now, before, earlier = (value(t - k * delta) for k in range(3))
    return (1.5 * (now - before) - 0.5 * (before - earlier)) / delta


def _path_rate(tangent: TangentStiffness, state: PETSc.Vec, t: float,
               delta: float) -> PETSc.Vec:
    """u' with K u' = -dR/dt at the state (Dirichlet rows: the motion's rate)."""
    system, problem = tangent.system, tangent.model.problem

    def residual(time: float) -> PETSc.Vec:
        problem.set_loads(time)
        problem.set_bcs(time)
        b = system.b.duplicate()
        system.residual(state, b)
        return b

    dR = -_backward_rate(residual, t, delta)  # -dR/dt
    problem.set_loads(t)
    problem.set_bcs(t)
    system.set(0, state)
    system.jacobian(system.A)                  # Dirichlet rows identity, columns kept
    ksp = PETSc.KSP().create(system.A.getComm())
    ksp.setOperators(system.A)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    rate = state.duplicate()
    ksp.solve(dR, rate)
    ksp.destroy()
    return rate
