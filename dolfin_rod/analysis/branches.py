"""Branch switching at a bifurcation of a quasi-static path (issue 27 item 2).

When the number of negative eigenvalues of the tangent stiffness K rises in a step
(StabilityMonitor), the path has crossed a critical point and the equilibrium Newton
followed is unstable: a straight column above Euler's load, a straight rod twisted past
Greenhill's moment.  A stable equilibrium at the same loads (natural strains frozen, as
in K) is found by going down the energy from the unstable state y_u, perturbed along the
critical mode v (K v = lambda_1 G v, LowestEigenvalues; G the lumped metric):

    y_0 = y_u + s PERTURBATION v  (RMS over the rod of PERTURBATION L),  s = +1, then -1,
    (K(y_k) + G / tau_k) dy = -F(y_k),  y_{k+1} = y_k + dy  (at most MAX_STEP per step),

pseudo-time steps of the gradient flow G y' = -F: with 1/tau = 2 |lambda_1| the mode
grows and the energy falls while K has more negative eigenvalues than before the step
(Newton there would return to the saddle y_u, its nearest root); once it has no more,
1/tau falls SHIFT_DECREASE-fold a step (Newton, quadratic at the end) until the step is
below DESCENT_STEP.  The state is then committed (the rod's stored rotations), settled
once more from there, and kept if it is stable: the run goes on from it with a warning.
The mode v: of the eigenvectors of the negative eigenvalues the combination the step's
load increment f does work along, sum (f . v_i) v_i (an imperfection's plane and side
for a double eigenvalue, the two planes of a round column), else the lowest one.
Newton on the amplitude of the mode (the load an unknown) does not serve here: from the
unstable state of an imperfect column the complementary branch it follows runs off to
infinite load instead of to the stable branch (tried, docs/stability.md).

Both rotation unknowns: on quaternions K is bordered by the gauge multiplier and G
measures the material rotations of quaternion directions (LowestEigenvalues), so the
modes, the descent and the switched branch are those of the rotation vectors
(tests/test_branches.py compares them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .eigen import EigenError, eigenpairs
from .stability import LowestEigenvalues, StabilityMonitor

__all__ = ["BranchSwitching", "Switch"]

PERTURBATION = 1e-3          # of the mode, RMS over L
MAX_DESCENT = 100
DESCENT_STEP = 1e-8          # relative to the problem's configuration norm
MAX_STEP = 0.02              # the same, a step's largest
SHIFT_DECREASE = 0.3
IMPERFECTION = 1e-10     # |f . v| / |f| (v^T G v = 1) below: no imperfection


@dataclass(frozen=True)
class Switch:
    """A bifurcation met at time t: the count of negative eigenvalues went from
    ``stable`` to ``unstable``; ``after`` is the count on the branch switched to (None:
    no stable branch was found, the path stays), ``sign`` the side of the mode the
    descent started on and ``steps`` its pseudo-time steps."""

    t: float
    stable: int
    unstable: int
    after: int | None = None
    sign: int = 0
    steps: int = 0


class BranchSwitching:
    """After each step of a quasi-static run (``check(t, t_before)``): the stability
    count of ``monitor`` and, when it rose, a switch to a stable branch (``switches``)."""

    def __init__(self, monitor: StabilityMonitor):
        tangent = monitor.tangent
        self.monitor, self.tangent = monitor, tangent
        self.modes = monitor.eigenvalues or LowestEigenvalues(tangent)
        self.problem = tangent.model.problem
        # the size of a configuration (steps are measured against it): the problem's
        # (rotation vectors), else (quaternions) sqrt(dofs) L
        self.scale = self.problem.configuration_norm() or \
            np.sqrt(tangent.system.x.getSize()) * tangent.model.length
        self._ksp = PETSc.KSP().create(self.problem.comm)     # K + G / tau: MUMPS LU
        self._ksp.setType("preonly")
        self._ksp.getPC().setType("lu")
        self._ksp.getPC().setFactorSolverType("mumps")
        self.switches: list[Switch] = []
        self.reported = 0       # switches the run has warned about
        self.checked_at: float | None = None

    def check(self, t: float, t_before: float) -> int:
        """The count at t after the step from t_before, switching branches if it rose."""
        self.checked_at = t
        stable = self.monitor.negative
        unstable = self.monitor.check(t)
        if stable is None or unstable <= stable:
            return unstable
        self.switches.append(self._switch(t, t_before, stable, unstable))
        return self.monitor.negative

    def _switch(self, t: float, t_before: float, stable: int, unstable: int) -> Switch:
        """From the unstable state at t, perturbed along the critical mode (one side,
        then the other), down the energy to a stable equilibrium at t's loads (descent),
        solved there and committed."""
        self.problem.set_bcs(t)     # rotation increments from the committed rotations
        at_t = _Snapshot(self.tangent)
        try:
            lowest, critical = self._critical_mode(t, t_before, at_t.vector,
                                                   unstable - stable)
        except EigenError:
            return Switch(t, stable, unstable)
        for sign in (1, -1):
            at_t.restore()
            trial = at_t.vector.copy()
            trial.axpy(sign * PERTURBATION, critical)
            steps = self._descend(t, trial, abs(lowest), stable)
            if steps is not None and self._settled(t, abs(lowest), stable):
                return Switch(t, stable, unstable, self.monitor.check(t, again=True),
                              sign, steps)
        at_t.restore()
        self.problem.set_loads(t)
        self.problem.set_bcs(t)
        return Switch(t, stable, unstable)

    def _descend(self, t: float, y, rate: float, stable: int) -> int | None:
        """Pseudo-time steps (G / tau + K) dy = -F(y) (G the metric of the modes) from
        y at t's loads: with 1/tau = 2 |lambda_1| (``rate``, the lowest eigenvalue at
        the unstable state) every step doubles the unstable mode's amplitude and
        decreases the energy while K has more than ``stable`` negative eigenvalues;
        then 1/tau falls SHIFT_DECREASE-fold a step (Newton) until the step is below
        DESCENT_STEP times the configuration norm.  The steps taken, or None if that
        does not happen in MAX_DESCENT steps."""
        system, ksp = self.tangent.system, self._ksp
        F, dy, A = y.duplicate(), y.duplicate(), system.A
        shift = 2.0 * rate
        for step in range(1, MAX_DESCENT + 1):
            self.problem.set_loads(t)
            system.set(0, y)
            system.residual(y, F)
            unstable = self._unstable(t, stable)
            shift = 2.0 * rate if unstable else SHIFT_DECREASE * shift
            system.jacobian(A)
            A.axpy(shift, self.modes.G, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
            ksp.setOperators(A)
            F.scale(-1.0)
            ksp.solve(F, dy)
            size = dy.norm()
            if not np.isfinite(size):
                return None
            y.axpy(min(1.0, MAX_STEP * self.scale / size), dy)
            if size < DESCENT_STEP * self.scale and not unstable:
                system.set(0, y)
                return step
        return None

    def _unstable(self, t: float, stable: int) -> bool:
        """Whether K has more than ``stable`` negative eigenvalues (a zero one, a
        neutral mode, counts as stable: StabilityMonitor.count)."""
        return self.monitor.count(t) > stable

    def _settled(self, t: float, rate: float, stable: int) -> bool:
        """The descended state committed (the rod's stored rotations take the rotation
        increments), descended again from there (the loads' rotations at quadrature
        points interpolate the increment: the committed state differs from the solved
        one at second order in it) and committed; whether it is no less stable than
        before the step."""
        self.problem.after_step()
        y = self.tangent.system.x.duplicate()
        self.tangent.system.get(0, y)
        self.problem.set_bcs(t)         # rotation increments from the committed rotations
        if self._descend(t, y, rate, stable) is None:
            return False
        self.problem.after_step()
        self.problem.set_bcs(t)
        return not self._unstable(t, stable)

    def _critical_mode(self, t: float, t_before: float, y, count: int):
        """The lowest eigenvalue and the critical mode: of the eigenvectors of the
        ``count`` lowest negative eigenvalues (eigenpairs: those nearest 0, twice as
        many, the negative ones) the combination the step's load increment f does work along (its projection
        sum (f . v_i) v_i: the side and, for a multiple eigenvalue, the plane an
        imperfection favours), the lowest one if f does none (a perfect structure);
        scaled to an RMS of L over the rod (v^T G v = L^3, G the metric of
        LowestEigenvalues)."""
        K = self.tangent.matrix(t)
        pairs = eigenpairs(K, self.modes.G, count=2 * count + 2, target=0.0)
        K.destroy()
        negative = sorted(((value, v) for value, v in zip(pairs.values, pairs.vectors)
                           if value < 0.0), key=lambda pair: pair[0])[:count]
        if not negative:
            raise EigenError("no negative eigenvalue among those nearest 0")
        vectors = [v for _, v in negative]
        increment = self._load_increment(y, t, t_before)
        works = [increment.dot(v) for v in vectors]
        mode = vectors[0]
        if max(map(abs, works)) > IMPERFECTION * increment.norm():
            mode = vectors[0].duplicate()
            mode.set(0.0)
            for work, v in zip(works, vectors):
                mode.axpy(work, v)
        metric = mode.duplicate()
        self.modes.G.mult(mode, metric)
        mode.scale(self.tangent.model.length ** 1.5 / np.sqrt(mode.dot(metric)))
        return negative[0][0], mode

    def _load_increment(self, y, t: float, t_before: float):
        """The loads' increment from t_before to t at the state y, -(F(y, t) -
        F(y, t_before)) (F = internal - external forces)."""
        now, before = y.duplicate(), y.duplicate()
        system = self.tangent.system
        system.set(0, y)
        for time, vector in ((t_before, before), (t, now)):
            self.problem.set_loads(time)
            system.residual(y, vector)
        before.axpy(-1.0, now)
        return before


class _Snapshot:
    """The mechanical state of a rod (its unknowns and stored rotations), to go back to."""

    def __init__(self, tangent):
        self.tangent = tangent
        model = tangent.model
        self.vector = tangent.system.x.duplicate()
        tangent.system.get(0, self.vector)
        self.state = model.checkpoint_state()
        self.stored = [f.x.array.copy() for f in self.state.get("functions", {}).values()]

    def restore(self) -> None:
        self.tangent.system.set(0, self.vector)
        for f, array in zip(self.state.get("functions", {}).values(), self.stored):
            f.x.array[:] = array
        self.tangent.model.restore_state(self.state)
