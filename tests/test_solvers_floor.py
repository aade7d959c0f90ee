"""Newton at the residual's round-off floor (fem/solvers.py, BlockSNES.round_off_floor).

A straight column (EI = 1, shear/axial stiffness B = 3e5, clamped-free, 4 cells) under
an axial dead tip load ramped to 0.9 P_cr = 0.9 pi^2/4 EI/L^2 with the default solver
options but snes_atol 1e-11 (below this rod's floor; the default, 1e-10 = the scene's
time.atol, lies above it, where Newton stops by snes_atol first).  The column stays straight and its axial strain is linear in
the load, so from the second step on the step predictor is the solution: each step
starts at the residual's round-off floor, above snes_atol; Newton's step then passes
the step test and the residual fluctuates there, above its start (measured 2.1e-11 at
t = 0.3; 1.8e-11..2.2e-11 from 1.1e-11..1.5e-11 at 32 cells).  Before, the check that the residual had not grown
refused that as a false SolverError (the run failed at t = 0.1 after 6 step cuts); now
a residual at or below the floor's estimate eps ||J| h|| passes.  The estimate must bound
the residual found there and stay a small fraction of the load (it is a round-off floor,
not a loose tolerance): measured 8.7e-10 here, 4e-10 relative to the load.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod.fem.solvers import BlockSNES
from dolfin_rod import TimeStepper
from dolfin_rod.rod import EndLoad, RodModel, RodParameters

B = 3e5
LOAD = 0.9 * math.pi ** 2 / 4


@pytest.mark.mpi
def test_a_step_that_starts_at_the_round_off_floor_is_accepted(monkeypatch):
    floors = []         # (floor, residual norm) where a step test's residual grew
    estimate = BlockSNES.round_off_floor

    def recorded(self):
        floors.append((estimate(self), self.snes.getFunctionNorm()))
        return floors[-1][0]
    monkeypatch.setattr(BlockSNES, "round_off_floor", recorded)

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
