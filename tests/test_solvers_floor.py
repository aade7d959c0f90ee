"""Newton at the residual's round-off floor (fem/solvers.py, BlockSNES.round_off_floor).

A straight column (EI = 1, shear/axial stiffness B = 3e5, clamped-free, 4 cells) under
an axial dead tip load ramped to 0.9 P_cr = 0.9 pi^2/4 EI/L^2 with the default solver
options but snes_atol 1e-11 (below this rod's floor; the default, 1e-10 = the scene's
time.atol, lies above it, where Newton stops by snes_atol first).  The column stays straight and its axial strain is linear in
the load, so from the second step on the step predictor is the solution: each step
starts at the residual's round-off floor, above snes_atol; Newton's step leaves the
residual there, above its start (measured 2.1e-11 at t = 0.3; 1.8e-11..2.2e-11 from
1.1e-11..1.5e-11 at 32 cells).  Before, the check that the residual had not grown
refused that as a false SolverError (the run failed at t = 0.1 after 6 step cuts); now
a residual at or below the floor's estimate eps || |J| (|y| + h) || passes where Newton
stalls (NewtonTest: an iteration that raised the norm).  The
estimate must bound the residual found there and stay a small fraction of the load (it
is a round-off floor, not a loose tolerance): measured 8.7e-10 here, 4e-10 relative to
the load.  The rule itself, on given residual norms: the tests at the end.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from dolfin_rod.fem import solvers
from dolfin_rod import TimeStepper
from dolfin_rod.rod import EndLoad, RodModel, RodParameters

B = 3e5
LOAD = 0.9 * math.pi ** 2 / 4


@pytest.mark.mpi
def test_a_step_that_starts_at_the_round_off_floor_is_accepted(monkeypatch):
    floors = []         # (floor, residual norm) of solutions checked against a floor
    check = solvers.residual_problem

    def recorded(snes, reason, norm, initial, floor=0.0, *args):
        if floor:
            floors.append((floor, norm))
        return check(snes, reason, norm, initial, floor, *args)
    monkeypatch.setattr(solvers, "residual_problem", recorded)

    rod = RodModel(RodParameters(length=1.0, A=(1.0,) * 3, B=(B,) * 3), n_cells=4,
                   model="hyperelastic", start="clamped", end="free",
                   end_loads=[EndLoad("force", (0.0, 0.0, -LOAD), lambda t: t)])
    rod.set_initial_state()
    TimeStepper(rod.problem, solver_options={"snes_atol": 1e-11}).run(0.0, 0.3, 0.1)
    # closed form: the axial force is -P t everywhere, the strain -P t / B (linear
    # elastic axial law of the hyperelastic rod), the tip moves by -P t L / B; the
    # tolerance 1e-9 relative is far above Newton's (1e-10 steps) and the floor
    x = rod.f["displacement"]
    coords = x.function_space.tabulate_dof_coordinates()[:, 0]
    n_owned = x.function_space.dofmap.index_map.size_local
    tip = np.flatnonzero(np.isclose(coords[:n_owned], 1.0))
    local = x.x.array.reshape(-1, 3)[tip[0]] if tip.size else np.zeros(3)
    u = MPI.COMM_WORLD.allreduce(local, op=MPI.SUM)
    assert u[2] == pytest.approx(-0.3 * LOAD / B, rel=1e-9)
    assert abs(u[0]) < 1e-14 and abs(u[1]) < 1e-14
    # the residual at every accepted solution lies below the estimated floor, and the
    # floor is a round-off level: below 1e-8 of the load (measured 8.7e-10)
    assert floors and all(norm <= floor for floor, norm in floors)
    assert max(floor for floor, _ in floors) < 1e-8 * LOAD
    assert any(1e-11 < norm for _, norm in floors)     # above snes_atol: the case was met


class Tolerances:
    """What NewtonTest reads of a SNES: the default tolerances (rtol 1e-10, atol 1e-10,
    stol 1e-10, 25 iterations; divergence tolerance 1e4)."""

    def getTolerances(self):
        return 1e-10, 1e-10, 1e-10, 25

    def getDivergenceTolerance(self):
        return 1e4


def reasons_of(norms, floor, force_scale=1.0):
    """NewtonTest's reasons at the residual norms of iterations 0, 1, ... (a step test
    never met: |dy| = |y|), with the round-off floor ``floor`` (None: one that must not
    be asked) and the ``force_scale``, and how often it asked for the floor."""
    asked = []

    def estimate():
        assert floor is not None, "the floor was asked of a solve that did not stall"
        asked.append(floor)
        return floor
    test = solvers.NewtonTest(Tolerances(), norms[0], 0.0, force_scale, floor=estimate)
    return [test(it, norm, lambda: (1.0, 1.0)) for it, norm in enumerate(norms)], len(asked)


def test_newton_accepts_a_stall_at_the_round_off_floor_and_nothing_else():
    """The rule of NewtonTest's floor (fem/solvers.py): a residual below snes_atol
    converges without asking it (a well-scaled solve: its iterates and result as
    before); a residual at most the floor converges only where Newton stalled (an
    iteration raised the norm): one still converging quadratically
    below the floor iterates on, and a stall above the floor (not an equilibrium: a
    residual round-off does not explain) is not accepted; the floor is asked once a
    solve.  Neither a residual nor a floor above NEWTON_FORCE_CAP = 1e-3 of the force
    scale is a round-off level (a barrier's Jacobian at an iterate deep in it: its
    floor estimate 9e6 N against a force scale of 0.05 N, tests/test_thin_obstacle.py),
    nor is anything without a force scale."""
    ok, go = PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS, 0
    assert reasons_of([1.0, 1e-3, 1e-7, 1e-11], None) == ([go, go, go, ok], 0)
    assert reasons_of([1.0, 1e-4, 5e-9, 6e-9], 1e-8) == ([go, go, go, ok], 1)
    assert reasons_of([1.0, 1e-4, 5e-9, 4e-9], 1e-8) == ([go, go, go, go], 0)
    assert reasons_of([1.0, 1e-6, 2e-6, 3e-6, 3e-9], 1e-8) == ([go, go, go, go, go], 1)
    # (each iteration is checked: growth at the floor converges, growth above does not)
    assert reasons_of([1e-9, 2e-9], 1e-8) == ([go, ok], 1)
    assert reasons_of([1e-7, 2e-7], 1e-8) == ([go, go], 1)
    # the cap: a stall above 1e-3 of the scale, a floor above it, no scale
    assert reasons_of([1.0, 1e-4, 5e-9, 6e-9], None, 1e-6) == ([go, go, go, go], 0)
    assert reasons_of([1.0, 1e-4, 5e-9, 6e-9], 2e-8, 1e-5) == ([go, go, go, go], 1)
    assert reasons_of([1.0, 1e-4, 5e-9, 6e-9], None, 0.0) == ([go, go, go, go], 0)


def test_the_residual_check_accepts_at_most_the_floor():
    """residual_problem (a solve reported converged checked at its solution): a residual
    above snes_atol passes at most the floor NewtonTest estimated, and is refused above
    it, naming the tolerance."""
    ok = PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
    assert solvers.residual_problem(Tolerances(), ok, 4e-9, 1.0, 1e-8) is None
    problem = solvers.residual_problem(Tolerances(), ok, 4e-8, 1.0, 1e-8)
    assert "4e-08, above the tolerance 1e-08" in problem
    assert "4e-08, above the tolerance 1e-10" in \
        solvers.residual_problem(Tolerances(), ok, 4e-8, 1.0)
