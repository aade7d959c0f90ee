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
loads and couples (dead ones too) make K non-symmetric; its symmetric part is factorised
(the energy criterion, which for non-conservative loads neither proves nor excludes
instability: the vibration modes decide, analysis/vibration.py; ``StabilityMonitor.
conservative`` says which, the run's warnings say so; docs/stability.md "Couples").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import dolfinx.fem as fem
import numpy as np
import ufl
from petsc4py import PETSc

from ..fem import form_cache
from .definiteness import BandedCholesky
from .eigen import eigenpairs
from ..fem.assembly import block_system, monolithic_layout
from ..fem.multipoint import ConstrainedSystem
from ..fem.fe_model import vertex_measure
from ..theory.quaternions import np_qmul
from ..theory.rotations import material_derivative_vector

__all__ = ["Inertia", "TangentStiffness", "LowestEigenvalues", "StabilityMonitor",
           "at_rest_map", "non_conservative", "symmetric_part"]

MECHANICAL = ("displacement", "rotation_increment", "quaternion")
MULTIPLIERS = ("gauge_multiplier", "constraint_multiplier")
# eigenvalues of K v = lambda G v above -ZERO max K_ii / max G_ii count as zero, not as
# negative by round-off (a neutral mode: the buckled shape of an axisymmetric rod turned
# about its axis; eps max K_ii / max G_ii ~ 6e-9 on the columns of tests/test_branches.py,
# where its eigenvalue came out -1.0e-10 serially and below 0 on 2 ranks), while a load
# 4e-6 off a critical one (the bisections of tests/test_stability.py) gives ~1e-5 there
ZERO = 1e-14


@dataclass(frozen=True)
class Inertia:
    """negative: eigenvalues of the tangent stiffness below zero on the free directions
    (0: a stable equilibrium); zero: null pivots (a singular tangent: a zero-energy
    mode, or exactly at a bifurcation)."""

    negative: int
    zero: int


def at_rest_map(model) -> dict:
    """Zero Functions for the rates and accelerations of a model's fields (ufl.replace):
    the residual of an equilibrium."""
    moving = [model.r[n] for n in model.names] + [
        a for a in getattr(model.problem, "accelerations", []) if a is not None]
    return {f: fem.Function(f.function_space) for f in moving}


def non_conservative(model) -> bool:
    """Whether a rod's loads make K non-symmetric: follower loads, and couples of any
    kind (a dead couple, fixed spatial components, does path-dependent work on finite
    3-D rotations: not conservative, Ziegler; Argyris 1982, "An excursion into large
    rotations"; its load stiffness is skew, docs/stability.md "Couples"), and active
    moments (M . delta u with M fixed: not the variation of an energy)."""
    loads = [*model.end_loads, *model.distributed_loads, *model.point_loads]
    return any(load.follower or load.kind != "force" for load in loads)


def symmetric_part(A: PETSc.Mat, fixed: PETSc.IS, diagonal: float) -> PETSc.Mat:
    """(A + A^T) / 2 as a new matrix, the rows and columns ``fixed`` (Dirichlet dofs)
    zero but ``diagonal`` on the diagonal; A's are zeroed too."""
    A.zeroRowsColumns(fixed, diag=diagonal)
    S = A.transpose(PETSc.Mat())          # (without an out argument: in place)
    S.axpy(1.0, A, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
    S.scale(0.5)
    S.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    return S


class TangentStiffness:
    """K of a RodModel at its current state and loads (``inertia(t)``); a model with
    segment contact (``problem.terms``) adds its pairs' energy Hessians (the pairs
    within the barrier's reach at the state), the joints' constraints (``links``) make it
    P^T K P on the free dofs.  ``banded``: the banded Cholesky test of ``inertia``
    first where it applies (False: MUMPS's count at every check)."""

    def __init__(self, model, banded: bool = True):
        names = [n for n in model.names if n in MECHANICAL + MULTIPLIERS]
        at_rest = at_rest_map(model)
        residuals = [model.residual[n] for n in names]
        bcs = [bc for n in names for bc in model.bcs_of(n)]
        self.model, self.names, self.banded = model, names, banded
        fields = [model.f[n] for n in names]
        # compiled once per structure (form_cache): a second model of the same structure
        # (a fit's trial) binds the kernels without building the forms (issue 30)
        key = form_cache.structure_key(residuals, "tangent", names) \
            if monolithic_layout(fields) else None
        forms = None if form_cache.lookup(key, model.mesh.comm) else \
            [ufl.replace(F, at_rest) for F in residuals]
        objects = [*form_cache.registry(residuals), *at_rest.values()]
        self.system = block_system(forms, [fields], bcs=bcs, cache=(key, objects))
        # segment contact (rod/pair_contact.py): the pairs' Hessians join K
        self.system.add_terms(model.problem.terms)
        links = [replace(link, block=names.index(model.names[link.block]))
                 for link in model.problem.links]
        if links:           # joints of a rod system: K on the free dofs, P^T K P
            self.system = ConstrainedSystem(self.system, fields, links)
        self.multipliers = self._free_dofs(model, [n for n in names if n in MULTIPLIERS])
        start = self.system.A.getOwnershipRange()[0]
        self.fixed = PETSc.IS().createGeneral(
            (self.system.bc_rows + start).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._ksp = None        # at the first check: its options are then read at once
        self._symmetric = None  # K as SBAIJ, the factorisation's input
        self._entries = 0       # K's stored entries when _symmetric was made
        self._banded: BandedCholesky | bool | None = None     # at the first check
        self._gauge: np.ndarray | None = None   # quaternions: each node's 4 rows of q
        self.fast_checks = 0    # checks the banded test decided (stable)

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

    def mode_shapes(self, vectors) -> list[dict[str, np.ndarray]]:
        """Vectors of K's layout as nodal values {"displacement", "rotation"}, the
        rotation the material rotation vector (quaternions: 2 vec(conj(q) dq)/|q|^2 of
        the state's q), each scaled to a largest displacement of 1 (if it has one; a mode
        whose displacement is round-off beside its rotation, 1e-8 L, is a turn alone: its
        displacement is set to 0 and its rotation scaled to 1); the state in the fields is
        kept."""
        from ..mpi import largest_on_ranks
        system, model = self.system, self.model
        state = system.x.copy()
        system.get(0, state)
        label = {"displacement": "displacement", "rotation_increment": "rotation",
                 "quaternion": "rotation"}
        q = model.f["quaternion"].x.array.reshape(-1, 4).copy() \
            if "quaternion" in self.names else None
        shapes = []
        try:
            for vector in vectors:
                self.set_direction(vector)
                shape = {label[n]: model.f[n].x.array.copy() for n in self.names
                         if n in label}
                if q is not None:
                    shape["rotation"] = material_rotation(q, shape["rotation"])
                size, turn = (largest_on_ranks(model.mesh.comm, float(np.max(
                    np.linalg.norm(shape[n].reshape(-1, 3), axis=1), initial=0.0)))
                    for n in ("displacement", "rotation"))
                if size <= 1e-8 * model.length * turn:   # a turn alone (a string's spin):
                    shape["displacement"][:] = 0.0       # its round-off is no shape
                    size = turn
                shapes.append({n: v / size for n, v in shape.items()} if size > 0 else shape)
        finally:
            system.set(0, state)
        return shapes

    def set_direction(self, vector: PETSc.Vec) -> None:
        """A direction of K's layout into the fields (the state there overwritten: set
        it back after reading them): joints' P v (no offset)."""
        system = self.system
        if not isinstance(system, ConstrainedSystem):
            system.set(0, vector)
            return
        y = system.P.createVecLeft()
        system.P.mult(vector, y)
        system.inner.set(0, y)

    def matrix(self, t: float | None, symmetric: bool = True) -> PETSc.Mat:
        """The symmetric part of K at time t's loads (None: the loads' values as set in
        the problem; ``symmetric`` False: K itself, non-symmetric with non-conservative
        loads), a new matrix, Dirichlet rows and columns identity."""
        A = self._assemble(t)
        if not symmetric:
            A.zeroRowsColumns(self.fixed, diag=1.0)
            return A.copy()
        return symmetric_part(A, self.fixed, 1.0)

    def unbalanced(self) -> float:
        """The largest entry of the residual at rest (rates and accelerations zero) at
        the current state and loads (after ``matrix``), on the free dofs (joints: P^T
        F): the force by which the state misses an equilibrium."""
        system = self.system
        system.residual(system.x, system.b)
        return system.b.norm(PETSc.NormType.INFINITY)

    def _assemble(self, t: float | None) -> PETSc.Mat:
        """K at the current state and time t's loads (None: as set), in the system's own
        matrix."""
        if t is not None:
            self.model.problem.set_loads(t)
        system = self.system
        system.get(0, system.x)
        system.set(0, system.x)
        if system.terms:        # the pairs' Hessians are those of the last residual's state
            system.residual(system.x, system.b)
        system.jacobian(system.A)
        return system.A

    def inertia(self, t: float, metric: PETSc.Mat | None = None) -> Inertia:
        """The inertia of K at the current state and time t's loads; with a ``metric``
        G, the negative count is that of the eigenvalues of K v = lambda G v below
        -ZERO max K_ii / max G_ii (of K + that shift times G).  On one rank without
        constraint multipliers a banded Cholesky first (analysis/definiteness.py, ``banded``):
        if it succeeds, K is positive definite, the count 0; otherwise, and on several
        ranks, MUMPS's LDL^T reads SBAIJ: one copy, kept, its values replaced at each
        check (K's pattern is fixed unless new segment-contact pairs grow it: then a
        new copy; G's is a part of it), so that MUMPS keeps its analysis (ordering,
        symbolic factorisation) and only refactorises."""
        A = self._assemble(t)
        if self._fast_test(A) and self._positive_definite(A, metric):
            self.fast_checks += 1
            return Inertia(0, 0)
        K = symmetric_part(A, self.fixed, 1.0)
        if metric is not None:
            shift = ZERO * _largest_diagonal(K) / _largest_diagonal(metric)
            K.axpy(shift, metric, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
            K.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        entries = K.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]
        if self._ksp is None or entries != self._entries:
            # first check, or new contact pairs grew K's pattern: a new analysis
            if self._ksp is not None:
                self._ksp.destroy()
                self._symmetric.destroy()
            self._symmetric = K.convert("sbaij", PETSc.Mat())
            self._ksp = self._factorisation(K.getComm())
            self._ksp.setOperators(self._symmetric)
            self._entries = entries
        else:
            K.convert("sbaij", self._symmetric)            # values only
        K.destroy()
        pc = self._ksp.getPC()
        pc.setUp()
        negative, zero, _ = pc.getFactorMatrix().getInertia()  # after setUp: this K's
        return Inertia(negative - self.multipliers, zero)

    def _fast_test(self, A: PETSc.Mat) -> bool:
        """Whether the banded Cholesky applies (made at the first check): one rank, an
        AIJ matrix, ``banded`` on, and no multipliers (they make K indefinite) but the
        quaternion gauge's (``_positive_definite``: its rows left out) on a rod without
        joints."""
        if self._banded is None:
            gauge = "quaternion" in self.names and "constraint_multiplier" not in self.names \
                and not isinstance(self.system, ConstrainedSystem)
            applies = (A.getComm().getSize() == 1 and A.getType() == "seqaij"
                       and (self.multipliers == 0 or gauge))
            fixed = self.system.bc_rows
            if applies and gauge:
                dofs = self.system.block_dofs
                quaternion = dofs[self.names.index("quaternion")]
                self._gauge = quaternion.reshape(-1, 4).astype(PETSc.IntType)
                fixed = np.union1d(fixed, dofs[self.names.index("gauge_multiplier")])
            self._banded = BandedCholesky(A.getSize()[0], fixed) if applies else False
        return self.banded and bool(self._banded)

    def _positive_definite(self, A: PETSc.Mat, metric: PETSc.Mat | None) -> bool:
        """The banded test of K (+ the metric's shift); quaternions: of K + c sum_i
        e_i e_i^T without the gauge's rows, e_i = q_i/|q_i| at node i, c the largest
        |K_ii|: on the directions the gauge leaves free (e_i . dq_i = 0) it is K, so
        its Cholesky succeeding means K is positive definite there, the count 0 (along
        e_i, where the energy is flat, it is c).  A is left as it was (c e_i e_i^T
        added, then subtracted)."""
        if self._gauge is None:
            return self._banded.positive_definite(A, metric, ZERO)
        q = self.model.f["quaternion"].x.array.reshape(-1, 4)
        e = q / np.linalg.norm(q, axis=1)[:, None]
        blocks = _largest_diagonal(A) * np.einsum("ni,nj->nij", e, e)

        def add(sign: float) -> None:
            for rows, block in zip(self._gauge, blocks):
                A.setValues(rows, rows, sign * block.ravel(), addv=PETSc.InsertMode.ADD_VALUES)
            A.assemble()

        add(1.0)
        try:
            return self._banded.positive_definite(A, metric, ZERO)
        finally:
            add(-1.0)

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


def _metric_forms(model, names: list[str]) -> tuple[list, list]:
    """The forms of LowestEigenvalues' metric G, one per block of ``names``, and the
    fields G is their derivative by: the displacement, the rotation increment or a
    direction dq of the quaternions at the state's q (its residual linear in dq), the
    gauge multiplier's own residual (no dq in it: zero rows)."""
    dx = vertex_measure(model.mesh)
    x = model.f["displacement"]
    forms = {"displacement": ufl.inner(x, model.t["displacement"]) * dx}
    fields = {"displacement": x}
    if "rotation_increment" in names:
        theta = fields["rotation_increment"] = model.f["rotation_increment"]
        forms["rotation_increment"] = model.length ** 2 * ufl.inner(
            theta, model.t["rotation_increment"]) * dx
    else:
        q = model.f["quaternion"]
        dq = fields["quaternion"] = fem.Function(q.function_space)
        forms["quaternion"] = model.length ** 2 * ufl.inner(
            material_derivative_vector(q, dq),
            material_derivative_vector(q, model.t["quaternion"])) * dx
        fields["gauge_multiplier"] = fem.Function(model.f["gauge_multiplier"].function_space)
        forms["gauge_multiplier"] = model.residual["gauge_multiplier"]
    return [forms[n] for n in names], [[fields[n] for n in names]]


def material_rotation(q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """2 vec(conj(q) dq)/|q|^2 at the nodes (q, dq: n x 4 and 4n values): a quaternion
    direction as the material rotation vector (theory/rotations.py's in numpy)."""
    dq = dq.reshape(-1, 4)
    conj = q * np.array([1.0, -1.0, -1.0, -1.0])
    vec = np_qmul(conj, dq)[:, 1:]
    return (2 * vec / np.sum(q * q, axis=1)[:, None]).ravel()


def _largest_diagonal(A: PETSc.Mat) -> float:
    return A.getDiagonal().norm(PETSc.NormType.INFINITY)


class LowestEigenvalues:
    """The lowest eigenvalues of K v = lambda G v on a rod without constraints, G the
    lumped metric int (dx . x + L^2 dtheta . theta) ds (vertex rule: diagonal per node;
    units of K per length^3, e.g. EI/L^4: independent of the mesh), by SLEPc
    (analysis/eigen.py: shift-and-invert at 0, MUMPS).  dtheta: the rotation increment,
    or for quaternions the material rotation 2 vec(conj(q) dq)/|q|^2 of a direction dq
    (K bordered by the gauge multiplier, whose rows and the direction dq along q have
    G = 0: the eigenvalues are those of the rotation increments).  Dirichlet dofs have
    G = 0 (infinite eigenvalues, out of the way)."""

    def __init__(self, tangent: TangentStiffness):
        model = tangent.model
        if "constraint_multiplier" in tangent.names:
            raise ValueError("lowest eigenvalues: a rod without constraints (no "
                             "material.constraint)")
        self.tangent = tangent
        bcs = [bc for n in tangent.names for bc in model.bcs_of(n)]
        self._system = block_system(*_metric_forms(model, tangent.names), bcs=bcs)
        self._moving = "quaternion" in tangent.names      # G depends on the state's q
        self._G: PETSc.Mat | None = None

    @property
    def G(self) -> PETSc.Mat:
        """G at the state in the fields (assembled once for rotation increments)."""
        if self._G is not None and not self._moving:
            return self._G
        system, joints = self._system, self.tangent.system
        system.jacobian(system.A)
        if not isinstance(joints, ConstrainedSystem):
            self._G = system.A
        else:                                                 # joints: P^T G P
            self._G = system.A.PtAP(joints.P, result=self._G)
        self._G.zeroRowsColumns(self.tangent.fixed, diag=0.0)
        return self._G

    def __call__(self, t: float, count: int = 1) -> list[float]:
        """The ``count`` eigenvalues nearest 0 at time t, ascending (all of them below 0
        when count exceeds the negative count)."""
        K = self.tangent.matrix(t)
        values = eigenpairs(K, self.G, count, target=0.0).values
        K.destroy()
        return sorted(values)


class StabilityMonitor:
    """The inertia after every step of a quasi-static run (``check(t)``): the count of
    negative eigenvalues, if asked the lowest eigenvalue (``lowest``; LowestEigenvalues),
    the times the count changed (``changes``: (t, before, after)), and the cost
    (``seconds`` over ``checks``); ``banded``: TangentStiffness's; ``conservative``:
    False for follower loads and couples (the count is then the energy criterion's, of
    K's symmetric part)."""

    def __init__(self, model, lowest: bool = False, banded: bool = True):
        self.tangent = TangentStiffness(model, banded)
        self.eigenvalues = LowestEigenvalues(self.tangent) if lowest else None
        self.metric = self._metric()     # LowestEigenvalues (its G) or None
        self.negative: int | None = None
        self._before: int | None = None     # the count before the last check
        self.lowest: float | None = None
        self.changes: list[tuple[float, int, int]] = []
        self.seconds, self.checks = 0.0, 0
        self.reported = 0       # changes the run has warned about
        self.conservative = not non_conservative(model)   # else: the energy criterion

    def _metric(self) -> LowestEigenvalues | None:
        """LowestEigenvalues, whose metric G exists without constraint multipliers: the
        count then takes round-off zero eigenvalues as zero (``count``)."""
        try:
            return self.eigenvalues or LowestEigenvalues(self.tangent)
        except ValueError:
            return None

    def count(self, t: float) -> int:
        """The negative eigenvalues of K at time t (eigenvalues within round-off of 0
        counted as 0 where the metric exists: TangentStiffness.inertia)."""
        return self.tangent.inertia(t, None if self.metric is None else self.metric.G).negative

    def check(self, t: float, again: bool = False) -> int:
        """The count at time t, recorded; ``again``: the state at t changed since the
        last check (a branch switch), which this one replaces (its change too)."""
        start = time.perf_counter()
        negative = self.count(t)
        if self.eigenvalues is not None:
            self.lowest = min(self.eigenvalues(t, negative + 1), default=float("nan"))
        self.seconds += time.perf_counter() - start
        if again:
            if self.changes and self.changes[-1][0] == t:
                self.changes.pop()
            self.negative = self._before
        else:
            self.checks += 1
            self._before = self.negative
        if self.negative is not None and negative != self.negative:
            self.changes.append((t, self.negative, negative))
        self.negative = negative
        return negative
