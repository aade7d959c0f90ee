"""Multi-point constraints on an assembled block system: joints between rods.

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

A ``NodeMap`` is a nonlinear link: y_slave = law(y_master, a) with p own parameters a
of the slave node (a hinge's angle, rod/joints.py), Newton unknowns stored in the
slave's first p rows of z.  Then y = Phi(z) + c, P = dPhi/dz at the current z (its map
rows refreshed at each ``set``: same pattern, new values), residual P^T F and its exact
Jacobian P^T J P + sum_i F_i d^2 Phi_i/dz^2 over the map's slave rows i (the law's
``curvature``: Newton converges quadratically); the map rows carry no offset (the law holds exactly at the solution, also from
an inconsistent predictor), and the law's own state is refreshed at each solve's start
(``get``: law.refresh(), collective).  For a field other than the law's
``configuration`` (rates, accelerations of the same block) the law's tangent at 0 is
used (law.value(..., exact=False)).  A map's master node must be free (not a slave).

A ``NodeLine`` is a one-node linear link: the node's values of a block move along a
unit ``axis`` only, y = y_0 + a axis (a support sliding along an axis that is not a
coordinate axis, or turning about one: rod/boundary_conditions.py).  Its component j of
largest |axis_j| stays free and the others are its slaves, y_i = (axis_i/axis_j) y_j
(+ the offset across the axis the state has when a solve starts, as a NodeLink's).
A ``NodePlane`` is its complement: the node's values stay in the plane normal . y =
normal . y_0 (one condition: the component of largest |normal_j| is the slave of the
others, y_j = -sum_i (normal_i/normal_j) y_i + offset; a quaternion's spin about its
director d3 held at one node, rod/boundary_conditions.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx.fem as fem
import numpy as np
from petsc4py import PETSc

__all__ = ["NodeLink", "NodeLine", "NodePlane", "NodeMap", "ConstrainedSystem"]


@dataclass(frozen=True)
class NodeLink:
    """y_slave = matrix @ y_master for block ``block`` at the nodes s = slave_s, master_s
    (matrix: bs x bs, bs the block's value size)."""

    block: int
    master_s: float
    slave_s: float
    matrix: tuple


@dataclass(frozen=True)
class _OneNode:
    """A link among the values of block ``block`` at one node s (master and slave)."""

    block: int
    s: float

    @property
    def master_s(self) -> float:
        return self.s

    slave_s = master_s


@dataclass(frozen=True)
class NodeLine(_OneNode):
    """The values of block ``block`` at the node s move along the unit ``axis`` only (see
    module)."""

    axis: tuple

    def weights(self) -> dict[int, dict[int, float]]:
        """{slave component i: {master component j: axis_i/axis_j}}."""
        a = np.asarray(self.axis, float)
        j = int(np.argmax(np.abs(a)))
        return {i: {j: a[i] / a[j]} for i in range(len(a)) if i != j}


@dataclass(frozen=True)
class NodePlane(_OneNode):
    """The values of block ``block`` at the node s stay in the plane of ``normal`` (see
    module)."""

    normal: tuple

    def weights(self) -> dict[int, dict[int, float]]:
        """{slave component j: {component i: -normal_i/normal_j}}."""
        c = np.asarray(self.normal, float)
        j = int(np.argmax(np.abs(c)))
        return {j: {i: -c[i] / c[j] for i in range(len(c)) if i != j and c[i] != 0.0}}


@dataclass(frozen=True)
class NodeMap:
    """y_slave = law.value(y_master, a) for block ``block`` at the nodes s = slave_s,
    master_s, with law.size own parameters a (see module).  The law: ``size``,
    ``configuration`` (the Function it holds exactly), ``refresh()`` (collective, at a
    solve's start), ``value(master, a, exact) -> (slave, dslave/d(master, a))``,
    ``curvature(master, a) -> d^2 slave/d(master, a)^2`` (of the exact law),
    ``parameters(master, slave, exact) -> a`` (the a that fits)."""

    block: int
    master_s: float
    slave_s: float
    law: object


def _owned_node_dofs(space, s: float) -> np.ndarray:
    """Owned local dofs (unrolled) of the node at s, in component order (empty if another
    rank owns it)."""
    nodes = fem.locate_dofs_geometrical(space, lambda x: np.isclose(x[0], s))
    nodes = nodes[nodes < space.dofmap.index_map.size_local]
    bs = space.dofmap.index_map_bs
    return (nodes[:, None] * bs + np.arange(bs)).ravel()


def node_rows(inner, fields: list, links: list) -> dict[tuple, int]:
    """{(link k, "master" | "slave", component i): global row of the inner system}, on
    every rank."""
    start = inner.x.getOwnershipRange()[0]
    found = []
    for k, link in enumerate(links):
        for side, s in (("master", link.master_s), ("slave", link.slave_s)):
            dofs = _owned_node_dofs(fields[link.block].function_space, s)
            rows = start + inner.block_dofs[link.block][dofs]
            found += [(k, side, i, int(r)) for i, r in enumerate(rows)]
    comm = inner.x.getComm().tompi4py()
    return {(k, side, i): r for part in comm.allgather(found) for k, side, i, r in part}


def _weights(link: NodeLink | NodeLine | NodePlane) -> dict[int, dict[int, float]]:
    """{slave component i: {master component j: weight}} of a linear link."""
    if isinstance(link, _OneNode):
        return link.weights()
    T = np.asarray(link.matrix, float)
    return {i: {j: T[i, j] for j in range(T.shape[1]) if T[i, j] != 0.0}
            for i in range(T.shape[0])}


def slave_rows(inner, fields: list, links: list) -> dict[int, dict[int, float]]:
    """{slave row: {master row: weight}} of the linear links (NodeLink, NodeLine) in the
    inner system's global rows, on every rank; a master that is itself a slave is
    replaced by its own masters."""
    row = node_rows(inner, fields, links)
    slaves: dict[int, dict[int, float]] = {}
    for k, link in enumerate(links):
        for i, masters in _weights(link).items():
            slaves[row[k, "slave", i]] = {row[k, "master", j]: w for j, w in masters.items()}
    for _ in range(len(links)):            # chains of links: masters that are slaves
        for target in slaves.values():
            for master in [m for m in target if m in slaves]:
                w = target.pop(master)
                for m, v in slaves[master].items():
                    target[m] = target.get(m, 0.0) + w * v
    return slaves


@dataclass
class _MappedNode:
    """A NodeMap on the assembled system: its master and slave rows (global rows of the
    inner system), the reduced columns of its arguments (masters, then own parameters)."""

    law: object
    masters: list
    slaves: list
    columns: list
    exact: bool
    owned: bool
    arguments: np.ndarray | None = None     # (masters, own parameters) at the last set


class _ReducedTerm:
    """A term of the inner system (assembly.add_terms) seen from the free dofs: its
    Newton-update limit (``limit_step``) on the prolonged state and update."""

    def __init__(self, system: "ConstrainedSystem", term):
        self.system, self.term = system, term

    def limit_step(self, z_owned: np.ndarray, dz_owned: np.ndarray) -> None:
        """dz (PETSc's sign: the new z is z - dz) scaled down in place by the factor the
        inner term gives to the update P dz at y = Phi(z) + c (a hinge's map linearised
        along the update)."""
        alpha = self.term.step_factor(*self.system.prolonged(z_owned, dz_owned))
        if alpha < 1.0:
            dz_owned *= alpha


class ConstrainedSystem:
    """A block system restricted by NodeLinks and NodeMaps to its free dofs (see module).
    Terms of the inner system that are not forms (segment contact, assembly.add_terms)
    enter through P^T and P^T J P like the forms; the pattern of J then grows with new
    contact pairs, so P^T J P is formed anew at each Jacobian (its symbolic product
    included) and inserted into A, whose pattern grows."""

    pattern_changes = 0     # A grows by insertion: PETSc's nonzero state shows it

    def __init__(self, inner, fields: list, links: list):
        self.inner, self.groups = inner, inner.groups
        self.terms = tuple(_ReducedTerm(self, term) for term in inner.terms
                           if hasattr(term, "step_factor"))     # those that add entries
        comm = inner.x.getComm()
        self._mpi = mpi = comm.tompi4py()
        start, stop = inner.x.getOwnershipRange()
        maps = [link for link in links if isinstance(link, NodeMap)]
        slaves = slave_rows(inner, fields, [link for link in links
                                            if not isinstance(link, NodeMap)])
        rows = node_rows(inner, fields, maps)
        bs = [fields[m.block].function_space.dofmap.index_map_bs for m in maps]
        mapped = {rows[k, "slave", i]: k for k, m in enumerate(maps) for i in range(bs[k])}
        own = {rows[k, "slave", i] for k, m in enumerate(maps) for i in range(m.law.size)}
        map_masters = {rows[k, "master", i] for k in range(len(maps)) for i in range(bs[k])}
        if map_masters & (set(slaves) | set(mapped)) or \
                set(mapped) & (set(slaves) | {m for t in slaves.values() for m in t}):
            raise ValueError("a nonlinear link's master node is tied to another node, or its "
                             "slave node is in another link: a hinge joins two nodes that "
                             "no other joint ties")
        free = [r for r in range(start, stop)
                if r not in slaves and (r not in mapped or r in own)]
        first = mpi.scan(len(free)) - len(free)
        local = dict(zip(free, range(first, first + len(free))))
        masters = {m for target in slaves.values() for m in target} | map_masters | own
        wanted = {m: local[m] for m in masters if m in local}
        reduced = {**local, **{k: v for part in mpi.allgather(wanted) for k, v in part.items()}}
        self.maps = [_MappedNode(
            m.law, [rows[k, "master", i] for i in range(bs[k])],
            [rows[k, "slave", i] for i in range(bs[k])],
            [reduced[rows[k, "master", i]] for i in range(bs[k])]
            + [reduced[rows[k, "slave", i]] for i in range(m.law.size)],
            fields[m.block] is m.law.configuration,
            start <= rows[k, "slave", 0] < stop) for k, m in enumerate(maps)]
        sizes = ((stop - start, None), (len(free), None))
        P = PETSc.Mat().createAIJ(sizes, nnz=(6, 6), comm=comm)
        R = PETSc.Mat().createAIJ((sizes[1], sizes[0]), nnz=(1, 1), comm=comm)
        for r in range(start, stop):
            if r in slaves:
                for m, w in slaves[r].items():
                    P.setValue(r, reduced[m], w)
            elif r in mapped:          # the pattern of dPhi/dz; values at each ``set``
                for column in self.maps[mapped[r]].columns:
                    P.setValue(r, column, 0.0)
            else:
                P.setValue(r, local[r], 1.0)
            if r in local:
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
        self._forces_current = False    # self._b: F at the state of the last set?
        self._slave_values = []
        if self.maps:
            self.get(0, self.x)        # the maps' derivatives at the fields' state
        inner.jacobian(inner.A)            # the structure of P^T J P (PtAP's symbolic part)
        self.A = inner.A.PtAP(P)

    def _values(self, vec, indices) -> dict:
        """{global index: value} of ``vec`` at ``indices``, on every rank."""
        low, high = vec.getOwnershipRange()
        array = vec.getArray(readonly=True)
        mine = {i: array[i - low] for i in indices if low <= i < high}
        return {i: v for part in self._mpi.allgather(mine) for i, v in part.items()}

    def _update_maps(self, z) -> None:
        """The maps' slave values and derivatives (P's map rows) at z."""
        if not self.maps:
            return
        values = self._values(z, [c for m in self.maps for c in m.columns])
        self._slave_values = []
        for m in self.maps:
            m.arguments = args = np.array([values[c] for c in m.columns])
            slave, derivative = m.law.value(args[:len(m.masters)], args[len(m.masters):],
                                            m.exact)
            if m.owned:
                self.P.setValues(m.slaves, m.columns, np.ravel(derivative))   # C order
                self._slave_values.append((m.slaves, slave))
        self.P.assemble()

    def _prolong(self, z) -> None:
        """self._y = Phi(z) + c: P z + c, the maps' rows by their laws."""
        self._update_maps(z)
        self.P.mult(z, self._y)
        self._y.axpy(1.0, self._c)
        start = self._y.getOwnershipRange()[0]
        for rows, values in self._slave_values:
            self._y.array_w[np.array(rows) - start] = values

    def set(self, k: int, z, blocks: bool = True) -> None:
        """Reduced vector -> y = Phi(z) + c -> group k."""
        self._forces_current = False
        self._prolong(z)
        self.inner.set(k, self._y, blocks)

    def get(self, k: int, z) -> None:
        """Group k -> y -> z = R y (the maps' own parameters fitted to y); the offset
        c = y - P z of the linear slaves kept (0 on the maps' rows); the maps' laws
        refreshed (a solve starts)."""
        self._forces_current = False
        for m in self.maps:
            m.law.refresh()
        self.inner.get(k, self._y)
        self.R.mult(self._y, z)
        if not self.maps:
            self.P.mult(z, self._c)
            self._c.aypx(-1.0, self._y)
            return
        values = self._values(self._y, [r for m in self.maps for r in m.masters + m.slaves])
        first = z.getOwnershipRange()[0]
        for m in self.maps:
            if m.owned:
                own = m.law.parameters(np.array([values[r] for r in m.masters]),
                                       np.array([values[r] for r in m.slaves]), m.exact)
                z.array_w[np.array(m.columns[len(m.masters):]) - first] = own
        self._update_maps(z)
        self.P.mult(z, self._c)
        self._c.aypx(-1.0, self._y)
        start = self._c.getOwnershipRange()[0]
        for rows, _ in self._slave_values:
            self._c.array_w[np.array(rows) - start] = 0.0

    def bc_values(self) -> np.ndarray:
        return self.inner.bc_values()

    def residual(self, z, b, bc_values=None) -> None:
        """b = P^T F(Phi(z) + c) (after ``set`` with the same z, as BlockSNES does); F
        kept for the Jacobian's curvature at this z (``_add_curvature``)."""
        self._prolong(z)
        self.inner.residual(self._y, self._b, bc_values)
        self._forces_current = True
        self.P.multTranspose(self._b, b)

    def jacobian(self, A) -> None:
        """P^T J P + sum_i F_i d^2 Phi_i/dz^2 (the exact maps' slave rows i) at the z of
        the last ``set``/``residual``."""
        self.inner.jacobian(self.inner.A)
        if self.terms:
            self._insert_product(A)
        else:
            self.inner.A.PtAP(self.P, result=A)
        if self.curved:
            self._add_curvature(A, self.curved)

    @property
    def curved(self) -> list:
        """The maps of the exact laws (their curvature is in the Jacobian)."""
        return [m for m in self.maps if m.exact]

    def carried(self, z) -> PETSc.Vec:
        """A copy of the inner residual F(Phi(z) + c) (after ``set`` with the same z): its
        slave rows are the forces the links carry."""
        self._prolong(z)
        self.inner.residual(self._y, self._b)
        self._forces_current = True
        return self._b.copy()

    def carried_rate(self, z, dz) -> PETSc.Vec:
        """The derivative of ``carried`` at z along dz, J(Phi(z) + c) P dz (a new vector;
        after ``set`` with the same z): the forces the links carry change at this rate."""
        self.carried(z).destroy()       # (the pairs' Hessians are those of the residual's state)
        self.inner.jacobian(self.inner.A)
        dy = self.P.createVecLeft()
        self.P.mult(dz, dy)
        rate = self._b.duplicate()
        self.inner.A.mult(dy, rate)
        dy.destroy()
        return rate

    def _insert_product(self, A) -> None:
        """A = P^T J P formed anew and inserted: J's pattern may have grown (pairs)."""
        product = self.inner.A.PtAP(self.P)
        rows, columns, values = product.getValuesCSR()        # owned rows
        start, stop = product.getOwnershipRange()
        # inserted (not a MatAXPY: its new header would hide the new pattern from the
        # LU, which must analyse it anew; MUMPS crashed)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        A.zeroEntries()
        A.setValuesIJV(rows, columns, values, rowmap=np.arange(start, stop,
                                                             dtype=PETSc.IntType))
        A.assemble()
        product.destroy()

    def _add_curvature(self, A, maps: list) -> None:
        """A += sum_i F_i d^2 slave_i/d(arguments)^2 on each map's columns, F the inner
        residual at y = Phi(z) + c (its slave rows: the force the map transmits): that of
        the last ``residual`` if no ``set`` came after it (Newton: the residual, then the
        Jacobian at the same iterate and loads), else assembled here."""
        if not self._forces_current:
            self.inner.residual(self._y, self._b)
            self._forces_current = True
        self.add_map_forces(A, maps, self._b)

    def add_map_forces(self, A, maps: list, F) -> None:
        """A += sum_i F_i d^2 slave_i/d(arguments)^2 on each map's columns, F a vector of
        the inner system's layout (its slave rows used) and the maps' arguments those of
        the last ``set``."""
        forces = self._values(F, [r for m in maps for r in m.slaves])
        for m in maps:
            if not m.owned:
                continue
            n = len(m.masters)
            H = m.law.curvature(m.arguments[:n], m.arguments[n:])
            carried = np.array([forces[r] for r in m.slaves])
            A.setValues(m.columns, m.columns, np.einsum("i,ikl->kl", carried, H).ravel(),
                        addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()

    def prolonged(self, z_owned: np.ndarray, dz_owned: np.ndarray):
        """(owned y = Phi(z) + c, owned P dz) of owned arrays of z and dz, as arrays of
        the inner system's layout (collective)."""
        z, dz = self.P.createVecRight(), self.P.createVecRight()
        z.array_w[:], dz.array_w[:] = z_owned, dz_owned
        self._prolong(z)
        dy = self.P.createVecLeft()
        self.P.mult(dz, dy)
        return self._y.getArray(readonly=True).copy(), dy.getArray(readonly=True).copy()
