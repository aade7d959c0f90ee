"""PETSc SNES on blocked forms (DOLFINx 0.9 ``*_block`` assembly), with failure reasons.

Blocks may include scifem real spaces (global scalar unknowns), so the uniform variant's
natural strains are solved monolithically with the fields, in serial and under MPI.
"""

from __future__ import annotations

import itertools

import dolfinx.fem as fem
import dolfinx.fem.petsc as fem_petsc
import numpy as np
import ufl
from ufl.algorithms import expand_derivatives
from dolfinx.cpp.la.petsc import scatter_local_vectors
from petsc4py import PETSc

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


def block_maps(forms):
    return [(f.function_spaces[0].dofmap.index_map, f.function_spaces[0].dofmap.index_map_bs)
            for f in forms]


def functions_to_vec(functions, x) -> None:
    """Copy block Functions into a block vector (owned entries, then ghosts)."""
    maps = [(u.function_space.dofmap.index_map, u.function_space.dofmap.index_map_bs)
            for u in functions]
    scatter_local_vectors(x, [u.x.array for u in functions], maps)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)


def vec_to_functions(x, functions) -> None:
    """Copy the owned entries of a block vector into block Functions and scatter ghosts."""
    offset = 0
    xa = x.getArray(readonly=True)
    for u in functions:
        n = u.function_space.dofmap.index_map.size_local * u.function_space.dofmap.index_map_bs
        u.x.array[:n] = xa[offset:offset + n]
        u.x.scatter_forward()
        offset += n


def jacobian_blocks(F: list[ufl.Form], y: list[fem.Function], wrt=None) -> list[list]:
    """dF_i/dy_j (or d/d wrt_j) as UFL forms; empty off-diagonal blocks are None.

    Empty diagonal blocks stay as zero forms: blocked assembly puts the unit diagonal of
    Dirichlet rows only into diagonal blocks that exist (explicit schemes have them).
    """
    wrt = y if wrt is None else wrt
    J = []
    for i, Fi in enumerate(F):
        row = []
        for j, (yj, xj) in enumerate(zip(y, wrt)):
            du = ufl.TrialFunction(yj.function_space)
            Jij = expand_derivatives(ufl.derivative(Fi, xj, du))
            if Jij.empty():
                Jij = None
                if i == j:
                    v = ufl.TestFunction(yj.function_space)
                    zero = fem.Constant(yj.function_space.mesh, 0.0)
                    Jij = zero * ufl.inner(du, v) * ufl.dx(domain=yj.function_space.mesh)
            row.append(Jij)
        J.append(row)
    return J


class BlockSNES:
    """Solve F_i(y) = 0 (one form per block) for the block Functions ``y`` with SNES.

    ``options`` are PETSc options under a private prefix (defaults: Newton with an exact
    line search off and MUMPS LU, which suits 1-D rods' banded systems).
    """

    def __init__(self, F: list[ufl.Form], y: list[fem.Function], bcs=(), options=None,
                 prefix: str | None = None):
        self.y = y
        self.bcs = list(bcs)
        self.F = fem.form(F)
        self.J = fem.form(jacobian_blocks(F, y))
        self.b = fem_petsc.create_vector_block(self.F)
        self.x = fem_petsc.create_vector_block(self.F)
        self.A = fem_petsc.create_matrix_block(self.J)
        self.snes = PETSc.SNES().create(self.x.getComm())
        self.snes.setFunction(self._residual, self.b)
        self.snes.setJacobian(self._jacobian, self.A)
        self.prefix = prefix or f"dolfin_rod_{next(_ids)}_"
        self.snes.setOptionsPrefix(self.prefix)
        opts = PETSc.Options()
        for k, v in {**DEFAULT_OPTIONS, **(options or {})}.items():
            opts[self.prefix + k] = v
        self.snes.setFromOptions()
        self.iterations = 0

    def _residual(self, snes, x, b):
        vec_to_functions(x, self.y)
        with b.localForm() as bl:
            bl.set(0.0)
        fem_petsc.assemble_vector_block(b, self.F, self.J, bcs=self.bcs, x0=x, alpha=-1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _jacobian(self, snes, x, A, P):
        A.zeroEntries()
        fem_petsc.assemble_matrix_block(A, self.J, bcs=self.bcs)
        A.assemble()

    def solve(self) -> int:
        """Newton from the current ``y``; on success ``y`` holds the solution."""
        functions_to_vec(self.y, self.x)
        self.snes.solve(None, self.x)
        reason = self.snes.getConvergedReason()
        self.iterations = self.snes.getIterationNumber()
        if reason <= 0 or not np.isfinite(self.snes.getFunctionNorm()):
            raise SolverError(_REASONS.get(reason, str(reason)), self.iterations)
        vec_to_functions(self.x, self.y)
        return self.iterations
