"""The stability of a quasi-static equilibrium: the inertia of the tangent stiffness.

At an equilibrium of a conservative rod the tangent stiffness K (the Hessian of the
energy in positions and rotations, natural strains frozen: they move on the viscous
time scale) is symmetric; the equilibrium is stable if K is positive definite on the
directions the supports and constraints leave free, and it has as many unstable modes
as K has negative eigenvalues there.  The count comes from the symmetric factorisation
L D L^T of MUMPS (Sylvester's law of inertia: its negative pivots, INFOG(12)), without
eigenvalues: one factorisation per check.  Multipliers (the quaternion gauge, the
constraints of Section 4.5) border K: [[K, C^T], [C, 0]] with C of full rank m has
(negative count of K on ker C) + m negative eigenvalues, so m is subtracted.
Dirichlet dofs are removed (identity rows and columns, positive pivots).  Follower
loads make K non-symmetric; its symmetric part is factorised (the energy criterion;
for non-conservative loads a dynamic analysis decides, not this count).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import dolfinx.fem as fem
import numpy as np
import ufl
from petsc4py import PETSc

from ..fem.assembly import block_system

__all__ = ["Inertia", "TangentStiffness", "StabilityMonitor"]

MECHANICAL = ("displacement", "rotation_increment", "quaternion")
MULTIPLIERS = ("gauge_multiplier", "constraint_multiplier")


@dataclass(frozen=True)
class Inertia:
    """negative: eigenvalues of the tangent stiffness below zero on the free directions
    (0: a stable equilibrium); zero: null pivots (a singular tangent: a zero-energy
    mode, or exactly at a bifurcation)."""

    negative: int
    zero: int


class TangentStiffness:
    """K of a RodModel at its current state and loads (``inertia(t)``)."""

    def __init__(self, model):
        names = [n for n in model.names if n in MECHANICAL + MULTIPLIERS]
        at_rest = {model.r[n]: fem.Function(model.r[n].function_space) for n in model.names}
        forms = [ufl.replace(model.residual[n], at_rest) for n in names]
        bcs = [bc for n in names for bc in model.bcs_of(n)]
        self.model, self.names = model, names
        self.system = block_system(forms, [[model.f[n] for n in names]], bcs=bcs)
        self.multipliers = self._free_dofs(model, [n for n in names if n in MULTIPLIERS])
        start = self.system.A.getOwnershipRange()[0]
        self._fixed = PETSc.IS().createGeneral(
            (self.system.bc_rows + start).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._ksp = None        # at the first check: its options are then read at once

    @staticmethod
    def _free_dofs(model, names) -> int:
        """Global dofs of the blocks ``names`` that no Dirichlet condition fixes."""
        total = 0
        for n in names:
            V = model.f[n].function_space
            imap = V.dofmap.index_map
            fixed = sum(bc.dof_indices()[1] for bc in model.bcs_of(n))   # owned ones
            total += (imap.size_global * V.dofmap.index_map_bs
                      - model.mesh.comm.allreduce(fixed))
        return total

    def matrix(self, t: float) -> PETSc.Mat:
        """The symmetric part of K at time t's loads, Dirichlet rows and columns identity."""
        self.model.problem.set_loads(t)
        system = self.system
        system.get(0, system.x)
        system.set(0, system.x)
        system.jacobian(system.A)
        A = system.A
        A.zeroRowsColumns(self._fixed, diag=1.0)
        K = A.transpose(PETSc.Mat())          # (without an out argument: in place)
        K.axpy(1.0, A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
        K.scale(0.5)
        K.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        return K

    def inertia(self, t: float) -> Inertia:
        """The inertia of K at the current state and time t's loads."""
        K = self.matrix(t).convert("sbaij", PETSc.Mat())   # MUMPS's LDL^T reads SBAIJ
        self._ksp = self._ksp or self._factorisation(K.getComm())
        self._ksp.setOperators(K)
        pc = self._ksp.getPC()
        pc.setUp()
        negative, zero, _ = pc.getFactorMatrix().getInertia()  # after setUp: this K's
        K.destroy()
        return Inertia(negative - self.multipliers, zero)

    def _factorisation(self, comm) -> PETSc.KSP:
        """MUMPS LDL^T; every pivot counted (no ScaLAPACK root, ICNTL(13)), null pivots
        detected (ICNTL(24)); kept between checks (MUMPS's start costs ms)."""
        ksp = PETSc.KSP().create(comm)
        prefix = f"dolfin_rod_inertia_{id(ksp)}_"
        ksp.setOptionsPrefix(prefix)
        opts = PETSc.Options()
        opts[prefix + "mat_mumps_icntl_13"] = 1
        opts[prefix + "mat_mumps_icntl_24"] = 1
        ksp.setType("preonly")
        pc = ksp.getPC()
        pc.setType("cholesky")
        pc.setFactorSolverType("mumps")
        ksp.setFromOptions()
        return ksp


class StabilityMonitor:
    """The inertia after every step of a quasi-static run (``check(t)``): the count of
    negative eigenvalues, the times it changed (``changes``: (t, before, after)), and the
    cost (``seconds`` over ``checks``)."""

    def __init__(self, model):
        self.tangent = TangentStiffness(model)
        self.negative: int | None = None
        self.changes: list[tuple[float, int, int]] = []
        self.seconds, self.checks = 0.0, 0
        self.reported = 0       # changes the run has warned about

    def check(self, t: float) -> int:
        start = time.perf_counter()
        negative = self.tangent.inertia(t).negative
        self.seconds += time.perf_counter() - start
        self.checks += 1
        if self.negative is not None and negative != self.negative:
            self.changes.append((t, self.negative, negative))
        self.negative = negative
        return negative
