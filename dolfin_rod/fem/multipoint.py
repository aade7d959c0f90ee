"""Linear multi-point constraints on an assembled block system: joints between rods.

A ``NodeLink`` ties the dofs of one block at a *slave* node to those at a *master* node,
y_slave = T y_master (+ the offset the state has when a solve starts), e.g. a rigid
joint of two rods: equal displacements (T = I; their offset is the difference of the
reference positions s e_3) and rotation increments turned into the slave's frame (T =
R_rel^T, rotation_vector.py).  ``ConstrainedSystem`` wraps an assembly.block_system
(same interface: x, b, A, set, get, residual, jacobian, bc_values) so that Newton works
on the free dofs z only:

    y = P z + c,    residual P^T F(y),    Jacobian P^T J P  (PETSc PtAP),

P the prolongation (identity rows for free dofs, T's rows for slave dofs), c the offset
of the slaves fixed at the start of each solve (c = y - P R y, R the restriction to the
free dofs).  The constraints hold exactly (no penalty, no multiplier) and the reduced
system keeps the size and structure of the rods' own (no saddle point).  A slave's
force is P^T's sum into its master: the joint's reaction is the slave rows of F.
A linked node must have no Dirichlet condition (checked by the model: joints join free
ends or interior nodes).
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx.fem as fem
import numpy as np
from petsc4py import PETSc

__all__ = ["NodeLink", "ConstrainedSystem"]


@dataclass(frozen=True)
class NodeLink:
    """y_slave = matrix @ y_master for block ``block`` at the nodes s = slave_s, master_s
    (matrix: bs x bs, bs the block's value size)."""

    block: int
    master_s: float
    slave_s: float
    matrix: tuple


def _owned_node_dofs(space, s: float) -> np.ndarray:
    """Owned local dofs (unrolled) of the node at s, in component order (empty if another
    rank owns it)."""
    nodes = fem.locate_dofs_geometrical(space, lambda x: np.isclose(x[0], s))
    nodes = nodes[nodes < space.dofmap.index_map.size_local]
    bs = space.dofmap.index_map_bs
    return (nodes[:, None] * bs + np.arange(bs)).ravel()


def slave_rows(inner, fields: list, links: list[NodeLink]) -> dict[int, dict[int, float]]:
    """{slave row: {master row: weight}} in the inner system's global rows, on every
    rank; a master that is itself a slave is replaced by its own masters."""
    start = inner.x.getOwnershipRange()[0]
    found = []
    for k, link in enumerate(links):
        for side, s in (("master", link.master_s), ("slave", link.slave_s)):
            dofs = _owned_node_dofs(fields[link.block].function_space, s)
            rows = start + inner.block_dofs[link.block][dofs]
            found += [(k, side, i, int(r)) for i, r in enumerate(rows)]
    comm = inner.x.getComm().tompi4py()
    row = {(k, side, i): r for part in comm.allgather(found) for k, side, i, r in part}
    slaves: dict[int, dict[int, float]] = {}
    for k, link in enumerate(links):
        T = np.asarray(link.matrix, float)
        for i in range(T.shape[0]):
            slaves[row[k, "slave", i]] = {row[k, "master", j]: T[i, j]
                                          for j in range(T.shape[1]) if T[i, j] != 0.0}
    for _ in range(len(links)):            # chains of links: masters that are slaves
        for target in slaves.values():
            for master in [m for m in target if m in slaves]:
                w = target.pop(master)
                for m, v in slaves[master].items():
                    target[m] = target.get(m, 0.0) + w * v
    return slaves


class ConstrainedSystem:
    """A block system restricted by NodeLinks to its free dofs (see module)."""

    terms: tuple = ()      # none: solvers.BlockSNES refuses terms with links

    def __init__(self, inner, fields: list, links: list[NodeLink]):
        self.inner, self.groups = inner, inner.groups
        comm = inner.x.getComm()
        start, stop = inner.x.getOwnershipRange()
        slaves = slave_rows(inner, fields, links)
        free = [r for r in range(start, stop) if r not in slaves]
        mpi = comm.tompi4py()
        first = mpi.scan(len(free)) - len(free)
        local = dict(zip(free, range(first, first + len(free))))
        masters = {m for target in slaves.values() for m in target}
        wanted = {m: local[m] for m in masters if m in local}
        reduced = {**local, **{k: v for part in mpi.allgather(wanted) for k, v in part.items()}}
        sizes = ((stop - start, None), (len(free), None))
        P = PETSc.Mat().createAIJ(sizes, nnz=(6, 6), comm=comm)
        R = PETSc.Mat().createAIJ((sizes[1], sizes[0]), nnz=(1, 1), comm=comm)
        for r in range(start, stop):
            if r in slaves:
                for m, w in slaves[r].items():
                    P.setValue(r, reduced[m], w)
            else:
                P.setValue(r, local[r], 1.0)
                R.setValue(local[r], r, 1.0)
        P.assemble()
        R.assemble()
        self.P, self.R = P, R
        # the Dirichlet rows among the free dofs (local reduced rows; no slave has one)
        self.bc_rows = np.array([local[start + r] - first for r in inner.bc_rows],
                                dtype=np.int32)
        self.x, self.b = P.createVecRight(), P.createVecRight()
        self._y, self._c, self._b = P.createVecLeft(), P.createVecLeft(), inner.b.duplicate()
        self._c.set(0.0)
        inner.jacobian(inner.A)            # the structure of P^T J P (PtAP's symbolic part)
        self.A = inner.A.PtAP(P)

    def set(self, k: int, z, blocks: bool = True) -> None:
        """Reduced vector -> y = P z + c -> group k."""
        self.P.mult(z, self._y)
        self._y.axpy(1.0, self._c)
        self.inner.set(k, self._y, blocks)

    def get(self, k: int, z) -> None:
        """Group k -> y -> z = R y; the offset c = y - P z of the slaves kept."""
        self.inner.get(k, self._y)
        self.R.mult(self._y, z)
        self.P.mult(z, self._c)
        self._c.aypx(-1.0, self._y)

    def bc_values(self) -> np.ndarray:
        return self.inner.bc_values()

    def residual(self, z, b, bc_values=None) -> None:
        """b = P^T F(P z + c) (after ``set`` with the same z, as BlockSNES does)."""
        self.P.mult(z, self._y)
        self._y.axpy(1.0, self._c)
        self.inner.residual(self._y, self._b, bc_values)
        self.P.multTranspose(self._b, b)

    def jacobian(self, A) -> None:
        self.inner.jacobian(self.inner.A)
        self.inner.A.PtAP(self.P, result=A)
