"""Residual vectors and Jacobians of blocked forms, as SNES and TS need them.

A model writes one form per block (problem.SemiDiscreteProblem); this module assembles
them in one of two layouts behind one interface (:func:`block_system`):

    MonolithicSystem  every block in one mixed element: one kernel call per vector or
                      matrix.  At rod sizes (10-100 cells) the blocked assembly's
                      per-block calls cost 5x the kernels (docs/performance.md).
    BlockedSystem     DOLFINx blocked assembly (compat.py: 0.9's ``*_block`` functions or
                      0.10+'s form lists); needed when a block is a real space (the
                      uniform variant's global natural strains), which the mixed element
                      does not hold.

Dirichlet conditions by row replacement: Jacobian rows of constrained dofs are identity
rows, residual rows are x - g.  The columns stay, so no lifting is needed and Newton is
exact also from iterates that violate the conditions (TS predictors, moving ends).
"""

from __future__ import annotations

import basix.ufl
import dolfinx.fem as fem
import dolfinx.fem.petsc as fem_petsc
import numpy as np
import ufl
from petsc4py import PETSc
from ufl.algorithms import expand_derivatives

from . import compat, form_cache, shared_mesh


def jacobian_blocks(F: list[ufl.Form], y: list[fem.Function], wrt=None,
                    zero: fem.Constant | None = None) -> list[list]:
    """dF_i/dy_j (or d/d wrt_j) as UFL forms; empty off-diagonal blocks are None.

    Empty diagonal blocks stay as zero forms (``zero`` times the mass: a Constant 0,
    made if not given) so that the block matrix has every diagonal entry (identity rows
    of constrained dofs; explicit schemes' algebraic blocks).
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
                    c = zero if zero is not None else fem.Constant(yj.function_space.mesh, 0.0)
                    Jij = c * ufl.inner(du, v) * ufl.dx(domain=yj.function_space.mesh)
            row.append(Jij)
        J.append(row)
    return J


def grow_pattern(A: PETSc.Mat, rows: np.ndarray, cols: np.ndarray) -> None:
    """A (assembled, AIJ) preallocated anew with its entries and their values plus zero
    entries at (rows, cols) (global numbers, owned rows; collective).  Entries added to
    an assembled matrix outside its pattern cost PETSc a reallocation each (a minute for
    the 4e5 entries of 1e4 segment pairs, docs/performance.md); in the pattern they cost
    a search in the row."""
    indptr, indices, values = A.getValuesCSR()
    start, n = A.getOwnershipRange()[0], len(indptr) - 1
    width = np.int64(A.getSize()[1])
    old = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)) * width + indices
    keys = np.union1d(old, (np.asarray(rows, np.int64) - start) * width + cols)
    merged = np.zeros(len(keys), dtype=values.dtype)
    merged[np.searchsorted(keys, old)] = values
    pointers = np.searchsorted(keys // width, np.arange(n + 1))
    A.setPreallocationCSR((pointers.astype(PETSc.IntType),
                           (keys % width).astype(PETSc.IntType), merged))


def _is_real(V) -> bool:
    """A real space: one global dof block on a mesh of several cells."""
    tdim = V.mesh.topology.dim
    return (V.dofmap.index_map.size_global == 1
            and V.mesh.topology.index_map(tdim).size_global > 1)


class _System:
    """Shared part: Dirichlet rows (owned, in the vector layout) and their values; terms
    assembled outside the forms (``add_terms``)."""

    terms: tuple = ()
    residual_terms = False  # whether a term adds to the residual (add_residual)
    pattern_changes = 0     # how often the terms grew the Jacobian's sparsity (grow_pattern)

    def _setup_bc_rows(self, bcs, rows_of):
        """rows_of(j, dofs): local rows of block j's (unrolled, owned) dofs."""
        self.rows_of = rows_of
        spaces = [y.function_space for y in self.groups[0]]
        self._bcs = []
        rows = []
        for bc in bcs:
            j = next(k for k, V in enumerate(spaces) if compat.contains(V, bc))
            dofs, first_ghost = bc.dof_indices()
            owned = dofs[:first_ghost]
            rows.append(rows_of(j, owned))
            self._bcs.append((bc, j, owned.astype(np.intp)))
        self.bc_rows = (np.concatenate(rows) if rows else np.zeros(0, dtype=np.int32))
        # numpy indexes with its own integer type: int32 indices cost a conversion at
        # each use (3x the indexing of a few rows)
        self._bc_index = self.bc_rows.astype(np.intp)
        start = self.x.getOwnershipRange()[0]
        self._bc_global = PETSc.IS().createGeneral(
            (self.bc_rows + start).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._scratch = [np.zeros_like(y.x.array) for y in self.groups[0]]
        self._set_matrix_options(self.A)

    def _set_matrix_options(self, A) -> None:
        A.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        # MPI: after the first assembly the off-rank entries go to the same ranks, and each
        # rank zeroes only its own (owned) rows: no rendezvous (BuildTwoSided) per Jacobian
        A.setOption(PETSc.Mat.Option.SUBSET_OFF_PROC_ENTRIES, True)
        A.setOption(PETSc.Mat.Option.NO_OFF_PROC_ZERO_ROWS, True)
        if any(hasattr(term, "add_jacobian") for term in self.terms):
            A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)

    def add_terms(self, terms) -> None:
        """Terms of the residual and Jacobian that are not forms (e.g. a rod's segment
        pairs in contact, rod/pair_contact.py): each ``term.bind(system)`` gives an object
        with add_residual(x_owned, b_owned) (before the Dirichlet rows are replaced),
        missing_entries() (the Jacobian entries it will add that A lacks, or None: the
        system then grows A's sparsity, ``pattern_changes`` counts it, and a solver
        that keeps a factorisation of A must set it up anew: under MPI PETSc's nonzero
        state of A does not always show the change) and add_jacobian(A) (global rows,
        before A.assemble()); a term may instead (or also) have prepare(x_owned), called
        before the forms are assembled at x (a mesh obstacle's features, rod/contact.py),
        and add nothing."""
        self.terms = tuple(term.bind(self) for term in terms)
        self.residual_terms = any(hasattr(term, "add_residual") for term in self.terms)
        self._set_matrix_options(self.A)

    def _prepare_terms(self, x) -> None:
        if self.terms:
            xa = x.getArray(readonly=True)
            for term in self.terms:
                if hasattr(term, "prepare"):
                    term.prepare(xa)

    def _add_terms_to_residual(self, x, b) -> None:
        if self.residual_terms:
            xa, ba = x.getArray(readonly=True), b.getArray()
            for term in self.terms:
                if hasattr(term, "add_residual"):
                    term.add_residual(xa, ba)

    def _add_terms_to_jacobian(self, A) -> None:
        for term in self.terms:
            if not hasattr(term, "add_jacobian"):
                continue
            entries = term.missing_entries()
            if entries is not None:
                A.assemble()
                grow_pattern(A, *entries)
                self._set_matrix_options(A)
                self.pattern_changes += 1
            term.add_jacobian(A)

    def bc_values(self) -> np.ndarray:
        """The prescribed values of the Dirichlet rows (in bc_rows' order), as set now."""
        vals = []
        for bc, j, owned in self._bcs:
            bc.set(self._scratch[j])
            vals.append(self._scratch[j][owned])
        return np.concatenate(vals) if vals else np.zeros(0)

    def _replace_bc_rows(self, x, b, bc_values) -> None:
        if len(self.bc_rows):
            self._bc_rows_into(x, b.array_w, bc_values)

    def _bc_rows_into(self, x, b_owned, bc_values) -> None:
        """The Dirichlet rows of the residual's owned entries ``b_owned``: x - g."""
        rows = self._bc_index
        values = self.bc_values() if bc_values is None else bc_values
        b_owned[rows] = x.getArray(readonly=True)[rows] - values

    def _identity_bc_rows(self, A) -> None:
        A.zeroRows(self._bc_global, diag=1.0)


def mixed_space(spaces: list) -> tuple:
    """The mixed space W of the blocks' ``spaces`` and, per block j, its local (unrolled)
    dofs -> W's local dofs, cell by cell."""
    mesh = spaces[0].mesh
    W = fem.functionspace(mesh, basix.ufl.mixed_element([V.ufl_element() for V in spaces]))
    cells = mesh.topology.index_map(mesh.topology.dim)
    ncells = cells.size_local + cells.num_ghosts
    maps = []
    for j, V in enumerate(spaces):
        bs = V.dofmap.index_map_bs
        cell_dofs = V.dofmap.list[:ncells]
        unrolled = (cell_dofs[:, :, None] * bs + np.arange(bs)).reshape(ncells, -1)
        m = np.empty((V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts) * bs,
                     dtype=np.int32)
        m[unrolled.ravel()] = W.sub(j).dofmap.list[:ncells].ravel()
        maps.append(m)
    return W, maps


class MonolithicSystem(_System):
    """All blocks in one mixed element; block Functions mirror the mixed ones.

    cache: (key, objects) or None: reuse the compiled forms of an earlier system with
    the same key (form_cache; F may then be None), else compile and remember them.
    """

    def __init__(self, F, groups, jacobian_terms, bcs, cache=None):
        self.groups = groups
        spaces = [y.function_space for y in groups[0]]
        mesh = spaces[0].mesh
        # the mixed space and the maps of the blocks' spaces: one per mesh kept for models
        # of one layout (shared_mesh.py; the role holds the spaces, so their ids stay theirs)
        _, W, self._maps = shared_mesh.space(mesh, ("mixed", *map(id, spaces)),
                                             lambda: (spaces, *mixed_space(spaces)))
        self.W = W
        self._indices = [m.astype(np.intp) for m in self._maps]     # (_bc_index)
        self.w = [fem.Function(W) for _ in groups]
        self._n_owned = W.dofmap.index_map.size_local
        # views fetched once (a DOLFINx array property costs ~1 us; set/get run 6-7
        # times per time step)
        self._w_arrays = [w.x.array for w in self.w]
        self._block_arrays = [[f.x.array for f in group] for group in groups]
        self._ghosted = mesh.comm.size > 1
        key, objects = cache if cache else (None, ())
        objects = [*objects, *self.w]
        entry = form_cache.lookup(key, mesh.comm)
        if entry is None:
            self.F, self.J, ufl_forms = self._compile(F, groups, jacobian_terms)
            if key:
                form_cache.store(key, self.F + self.J, ufl_forms, objects)
        else:
            forms = form_cache.bind(entry, objects, W, mesh)
            self.F = [f for f in forms if f.rank == 1]
            self.J = [f for f in forms if f.rank == 2]
        # the vectors and the Jacobian's pattern: duplicates of those of the first system of
        # this key on the space (its matrix once assembled: a DOLFINx matrix has no pattern
        # before), without DOLFINx's index maps and sparsity pattern, which make MPI calls
        # even on one rank (docs/performance.md, twelfth round)
        self._layout = layout = shared_mesh.space(mesh, ("system layout", key, id(W)),
                                                  dict) if key else {}
        if "x" not in layout:
            layout["x"] = compat.vector(self.F[0])
        self.x, self.b = layout["x"].duplicate(), layout["x"].duplicate()
        if "A" in layout:
            self.A = layout["A"].duplicate(copy=False)     # the pattern, zero values
            self.A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)  # (as
        else:                                                   # create_matrix sets it)
            self.A = fem_petsc.create_matrix(self.J[0])
        self._keep_pattern = bool(key) and "A" not in layout    # (jacobian)
        self._setup_bc_rows(bcs, lambda j, dofs: self._maps[j][dofs])
        # collective, so that no rank waits for one that raised (seen with < 2 cells a rank)
        if self.W.mesh.comm.allreduce(int(np.any(self.bc_rows >= self._n_owned))):
            raise RuntimeError("an owned Dirichlet dof maps to a ghost of the mixed space "
                               "(a rank with fewer than 2 cells?): use more cells or fewer "
                               "MPI ranks")

    def _compile(self, F, groups, jacobian_terms):
        """Residual and Jacobian forms on the mixed space, and their UFL forms."""
        W = self.W
        v = ufl.split(ufl.TestFunction(W))
        mapping = {f: part for group, w in zip(groups, self.w)
                   for f, part in zip(group, ufl.split(w))}
        F_mixed = 0
        for i, Fi in enumerate(F):
            (arg,) = Fi.arguments()
            F_mixed += ufl.replace(Fi, {**mapping, arg: v[i]})
        dw = ufl.TrialFunction(W)
        # One kernel per quadrature rule: FFCx 0.9 miscompiles mixed-element kernels that
        # combine the vertex rule with Gauss rules (wrong vertex-rule terms, measured), and
        # also some that combine the 1- and 2-point Gauss rules (the prototype's earlier
        # strain formula: a wrong Jacobian, Newton stalls; measured 2026-11-23).  The cause:
        # fem/quadrature_rules.py (midpoint values of sub-expressions the 1-point rule shares).
        residuals, jacobians = [], []
        for part in _split_by_rule(F_mixed):
            residuals.append(part)
            Jp = expand_derivatives(sum(c * ufl.derivative(part, self.w[k], dw)
                                        for c, k in jacobian_terms))
            if not Jp.empty():
                jacobians.append(Jp)
        return (form_cache.compile_forms(residuals), form_cache.compile_forms(jacobians),
                residuals + jacobians)

    @property
    def block_dofs(self) -> tuple[np.ndarray, ...]:
        """Per block j, read-only: its local (unrolled) dofs -> the mixed space's local
        dofs (owned block dofs map to owned mixed dofs)."""
        views = tuple(m.view() for m in self._maps)
        for v in views:
            v.flags.writeable = False
        return views

    def set(self, k: int, x, blocks: bool = True) -> None:
        """Vector -> group k (mixed Function and, if ``blocks``, its block Functions;
        ghosts updated).  The forms read the mixed Function only."""
        w = self._w_arrays[k]
        w[:self._n_owned] = x.getArray(readonly=True)
        if self._ghosted:
            self.w[k].x.scatter_forward()
        for f, m in zip(self._block_arrays[k], self._indices) if blocks else ():
            f[:] = w[m]

    def get(self, k: int, x) -> None:
        """Group k's block Functions -> vector."""
        w = self._w_arrays[k]
        for f, m in zip(self._block_arrays[k], self._indices):
            w[m] = f
        x.array_w[:] = w[:self._n_owned]

    def residual(self, x, b, bc_values=None) -> None:
        """b = F(x), Dirichlet rows x - g (g: ``bc_values`` if given, else bc_values())."""
        self._prepare_terms(x)
        # one rank (no ghosts to add to the owned rows) without terms' forces: the
        # Dirichlet rows written into the forms' array at once (2-3 us a residual)
        at_once = not (self._ghosted or self.residual_terms) and len(self.bc_rows)
        with b.localForm() as bl:       # (one local form for all forms: DOLFINx's
            bl.set(0.0)                 # PETSc assemble_vector takes one per form)
            array = bl.array_w
            for form in self.F:
                fem.assemble_vector(array, form)
            if at_once:
                self._bc_rows_into(x, array, bc_values)
            del array                   # (released inside the local form: b marked changed)
        if at_once:
            return
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        self._add_terms_to_residual(x, b)
        self._replace_bc_rows(x, b, bc_values)

    def jacobian(self, A) -> None:
        A.zeroEntries()
        for form in self.J:
            fem_petsc.assemble_matrix(A, form)
        self._add_terms_to_jacobian(A)
        A.assemble()
        self._identity_bc_rows(A)
        if self._keep_pattern and A is self.A:
            self._keep_pattern = False
            if "A" not in self._layout and not any(hasattr(term, "add_jacobian")
                                                   for term in self.terms):
                self._layout["A"] = A.duplicate(copy=False)     # the forms' pattern alone


# the blocks (i, j) of the Jacobian that exist, per form_cache key of a blocked system
_BLOCK_LAYOUTS: dict[str, list[tuple[int, int]]] = {}


class BlockedSystem(_System):
    """DOLFINx blocked assembly (block vectors: the blocks' owned entries in turn).

    cache: (key, objects) or None, as MonolithicSystem's (F may be None on a hit): the
    compiled blocks are kept in this process only, with the layout of the Jacobian's
    blocks; a second system of the key (a model of a real-space unknown: the uniform
    variant, torsion with global unknowns) skips the derivatives and the compile.
    """

    def __init__(self, F, groups, jacobian_terms, bcs, cache=None):
        self.groups = groups
        y = groups[0]
        key, objects = cache if cache else (None, ())
        zero = fem.Constant(y[0].function_space.mesh, 0.0)    # the empty diagonal blocks'
        objects = [*objects, zero]
        entry = form_cache.lookup(key, y[0].function_space.mesh.comm,
                                  usable=key in _BLOCK_LAYOUTS)
        if entry is None:
            terms = [(c, jacobian_blocks(F, y, wrt=groups[k], zero=zero))
                     for c, k in jacobian_terms]
            J = [[_combine(terms, i, j) for j in range(len(y))] for i in range(len(y))]
            self.F, self.J = form_cache.compile_forms(F), form_cache.compile_forms(J)
            if key:
                layout = [(i, j) for i, row in enumerate(J) for j, form in enumerate(row)
                          if form is not None]
                form_cache.store(key, [*self.F, *(self.J[i][j] for i, j in layout)],
                                 [*F, *(J[i][j] for i, j in layout)], objects, disk=False)
                _BLOCK_LAYOUTS[key] = layout
        else:
            layout, V = _BLOCK_LAYOUTS[key], [f.function_space for f in y]
            forms = form_cache.bind(entry, objects, [*([V[i]] for i in range(len(y))),
                                                     *([V[i], V[j]] for i, j in layout)],
                                    y[0].function_space.mesh)
            self.F, self.J = forms[:len(y)], [[None] * len(y) for _ in y]
            for (i, j), form in zip(layout, forms[len(y):]):
                self.J[i][j] = form
        self.x = compat.block_vector(self.F)
        self.b = compat.block_vector(self.F)
        self.A = compat.block_matrix(self.J)
        sizes = [f.function_space.dofmap.index_map.size_local
                 * f.function_space.dofmap.index_map_bs for f in y]
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        self._sizes = sizes
        self._setup_bc_rows(bcs, lambda j, dofs: (offsets[j] + dofs).astype(np.int32))

    def set(self, k: int, x, blocks: bool = True) -> None:
        offset = 0
        xa = x.getArray(readonly=True)
        for f, n in zip(self.groups[k], self._sizes):
            f.x.array[:n] = xa[offset:offset + n]
            f.x.scatter_forward()
            offset += n

    def get(self, k: int, x) -> None:
        compat.functions_to_block_vector(self.groups[k], x)

    def residual(self, x, b, bc_values=None) -> None:
        self._prepare_terms(x)
        with b.localForm() as bl:
            bl.set(0.0)
        compat.assemble_block_vector(b, self.F, self.J)
        self._add_terms_to_residual(x, b)
        self._replace_bc_rows(x, b, bc_values)

    def jacobian(self, A) -> None:
        A.zeroEntries()
        compat.assemble_block_matrix(A, self.J)
        self._add_terms_to_jacobian(A)
        A.assemble()
        self._identity_bc_rows(A)


def _split_by_rule(form: ufl.Form) -> list[ufl.Form]:
    """The integrals of ``form`` grouped by their quadrature metadata, one form each."""
    groups: dict = {}
    for itg in form.integrals():
        groups.setdefault(tuple(sorted(itg.metadata().items())), []).append(itg)
    return [ufl.Form(itgs) for itgs in groups.values()]


def _combine(terms, i, j):
    """sum_k c_k J_k[i][j] over the blocks that exist (None if none does)."""
    forms = [blocks[i][j] if isinstance(c, float) and c == 1.0 else c * blocks[i][j]
             for c, blocks in terms if blocks[i][j] is not None]
    return sum(forms[1:], forms[0]) if forms else None


def monolithic_layout(fields) -> bool:
    """Whether block_system assembles ``fields`` in one mixed element (no real space;
    else in blocks: BlockedSystem)."""
    return not any(_is_real(f.function_space) for f in fields)


def block_system(F: list[ufl.Form] | None, groups: list[list[fem.Function]],
                 jacobian_terms=((1.0, 0),), bcs=(), monolithic: bool | None = None,
                 cache=None):
    """The assembled system of block residuals ``F`` (F_i linear in a test function on
    the space of groups[0][i]).

    groups:          lists of block Functions the forms depend on and the caller sets
                     from vectors: groups[0] the unknowns y, then e.g. dy/dt for TS.
    jacobian_terms:  [(c, k)]: J = sum c dF/d(groups[k]) (c a float or fem.Constant).
    monolithic:      None: mixed element unless a block is a real space.
    cache:           (key, objects): compiled forms shared by systems of one structure
                     (form_cache; F may be None on a hit: form_cache.lookup(key)).
    """
    if monolithic is None:
        monolithic = monolithic_layout(groups[0])
    groups = [list(g) for g in groups]
    if monolithic:
        return MonolithicSystem(F and list(F), groups, list(jacobian_terms), list(bcs), cache)
    return BlockedSystem(F and list(F), groups, list(jacobian_terms), list(bcs), cache)
