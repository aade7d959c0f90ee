"""PETSc SNES on blocked forms (assembly.block_system), with failure reasons.

Blocks may include scifem real spaces (global scalar unknowns), so the uniform variant's
natural strains are solved monolithically with the fields, in serial and under MPI.
"""

from __future__ import annotations

import itertools

import dolfinx.fem as fem
import numpy as np
import ufl
from petsc4py import PETSc

from .assembly import block_system

_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-11,
    "snes_stol": 1e-10,  # |dx| < 1e-10 |x|: converged (x then exact to ~|dx|^2); a
                         # residual floor alone cannot be met at round-off on fine meshes
    "snes_max_it": 25,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
# Modified Newton for dynamics with small steps: the Jacobian and its LU are refreshed
# every 10 iterations and kept across time steps; 3-4x cheaper steps from 1e3 cells
# (docs/performance.md).  Large quasi-static load steps diverge with a stale Jacobian.
# Use as BlockSNES/TimeStepper solver_options.
JACOBIAN_REUSE = {
    "snes_lag_jacobian": 10,
    "snes_lag_jacobian_persists": True,
    "snes_lag_preconditioner": 10,
    "snes_lag_preconditioner_persists": True,
}
_ids = itertools.count()


class SolverError(RuntimeError):
    """SNES did not converge; ``reason`` is PETSc's converged-reason name."""

    def __init__(self, reason: str, iterations: int):
        super().__init__(f"SNES failed: {reason} after {iterations} iterations")
        self.reason = reason
        self.iterations = iterations


class BlockSNES:
    """Solve F_i(y) = 0 (one form per block) for the block Functions ``y`` with SNES.

    ``options`` are PETSc options under a private prefix (defaults: Newton with an exact
    line search off and MUMPS LU, which suits 1-D rods' banded systems).
    """

    def __init__(self, F: list[ufl.Form], y: list[fem.Function], bcs=(), options=None,
                 prefix: str | None = None, monolithic: bool | None = None):
        self.y = y
        self.system = block_system(F, [y], bcs=bcs, monolithic=monolithic)
        self.x = self.system.x
        self.snes = PETSc.SNES().create(self.x.getComm())
        self.snes.setFunction(self._residual, self.system.b)
        self.snes.setJacobian(self._jacobian, self.system.A)
        self.prefix = prefix or f"dolfin_rod_{next(_ids)}_"
        self.snes.setOptionsPrefix(self.prefix)
        opts = PETSc.Options()
        for k, v in {**DEFAULT_OPTIONS, **(options or {})}.items():
            opts[self.prefix + k] = v
        self.snes.setFromOptions()
        self.iterations = 0

    def _residual(self, snes, x, b):
        self.system.set(0, x)
        self.system.residual(x, b)

    def _jacobian(self, snes, x, A, P):
        self.system.jacobian(A)

    def solve(self) -> int:
        """Newton from the current ``y``; on success ``y`` holds the solution."""
        self.system.get(0, self.x)
        self.snes.solve(None, self.x)
        reason = self.snes.getConvergedReason()
        self.iterations = self.snes.getIterationNumber()
        if reason <= 0 or not np.isfinite(self.snes.getFunctionNorm()):
            raise SolverError(_REASONS.get(reason, str(reason)), self.iterations)
        self.system.set(0, self.x)
        return self.iterations
