"""Every difference between the supported DOLFINx releases, 0.9 and 0.11, in one place.

The rest of the package calls these functions and never checks a version.

    blocked assembly   0.9: ``create_vector_block``/``assemble_*_block``;
                       0.10+: ``create_vector(spaces)``, ``assemble_*`` on form lists
    real spaces        0.9: scifem's ``create_real_functionspace`` (collective on
                       COMM_WORLD); 0.10+: basix's ``real_element`` (on the mesh's comm)
    element data       0.9: ``interpolation_points()`` a method; 0.10+: a property
    geometry dofmap    0.9: ``geometry.dofmap``; 0.11: ``geometry.dofmaps[0]`` (the
                       former deprecated, with a warning)
    LinearProblem      0.10+: needs ``petsc_options_prefix``
    create_mesh        0.9: (comm, cells, x, domain); 0.10+: (comm, cells, element, x);
                       0.10+'s partitioner takes the facet-to-cell link limit
    C++ Form           0.9: the ufcx pointer and a dict of subdomain data; 0.10+: a list
                       of pointers and a list (a cached kernel's form, fem/form_cache.py)
    Python warnings    0.9: importing FFCx (dolfinx does) routes every warning to a logger
                       with no handler (``logging.captureWarnings(True)``), so the
                       package's warnings (a cut step, a first-order restart) were never
                       shown; undone here, they reach stderr as on 0.11
    numba              0.9: ``dolfinx.utils`` imports numba for optional helpers this
                       package never uses (0.2-0.5 s, a third of DOLFINx's import);
                       0.11 does not.  A run hides it while it imports the stack and
                       makes it importable again right after
                       (``run.import_finite_elements``: it must act before DOLFINx is
                       imported, which this module does at its top)
    SNES reasons       a non-finite residual norm: 0.9's PETSc 3.22 DIVERGED_FNORM_NAN,
                       0.11's PETSc 3.25 DIVERGED_FUNCTION_NANORINF (``NONFINITE_NORM``)
"""

from __future__ import annotations

import itertools
import logging

import dolfinx
import dolfinx.fem as fem
import dolfinx.fem.petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

DOLFINX_VERSION = tuple(int(x) for x in dolfinx.__version__.split(".")[:2])
_BLOCK_ASSEMBLERS = DOLFINX_VERSION < (0, 10)   # the *_block functions (removed in 0.10)
_prefixes = itertools.count()
logging.captureWarnings(False)     # FFCx 0.9 captured them (see above)
_reasons = PETSc.SNES.ConvergedReason
NONFINITE_NORM = (_reasons.DIVERGED_FNORM_NAN if hasattr(_reasons, "DIVERGED_FNORM_NAN")
                  else _reasons.DIVERGED_FUNCTION_NANORINF)


def vector(form: fem.Form) -> PETSc.Vec:
    """A ghosted vector in the layout of the linear form's test space."""
    if _BLOCK_ASSEMBLERS:
        return fem_petsc.create_vector(form)
    return fem_petsc.create_vector(form.function_spaces[0])


def block_vector(forms: list[fem.Form]) -> PETSc.Vec:
    """A vector of the blocks of linear forms: every block's owned entries, then ghosts."""
    if _BLOCK_ASSEMBLERS:
        return fem_petsc.create_vector_block(forms)
    return fem_petsc.create_vector([f.function_spaces[0] for f in forms])


def block_matrix(forms: list[list]) -> PETSc.Mat:
    """One (not nested) matrix of the bilinear forms' blocks (None: an empty block)."""
    if _BLOCK_ASSEMBLERS:
        return fem_petsc.create_matrix_block(forms)
    return fem_petsc.create_matrix(forms)


def assemble_block_vector(b: PETSc.Vec, forms: list[fem.Form], jacobian: list[list]) -> None:
    """b += the blocks of ``forms``, ghost contributions summed on their owners.

    ``jacobian`` (the bilinear blocks) is what DOLFINx 0.9's interface asks for; without
    boundary conditions it is not used.
    """
    if _BLOCK_ASSEMBLERS:
        fem_petsc.assemble_vector_block(b, forms, jacobian, bcs=[])
        return
    fem_petsc.assemble_vector(b, forms)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)


def assemble_block_matrix(A: PETSc.Mat, forms: list[list]) -> None:
    """A += the bilinear blocks (no boundary conditions; A.assemble() is the caller's)."""
    if _BLOCK_ASSEMBLERS:
        fem_petsc.assemble_matrix_block(A, forms, bcs=[])
    else:
        fem_petsc.assemble_matrix(A, forms, bcs=[])


def functions_to_block_vector(functions: list[fem.Function], x: PETSc.Vec) -> None:
    """Copy the Functions' values into the block vector x, ghosts included."""
    if _BLOCK_ASSEMBLERS:
        from dolfinx.cpp.la.petsc import scatter_local_vectors
        maps = [(f.function_space.dofmap.index_map, f.function_space.dofmap.index_map_bs)
                for f in functions]
        scatter_local_vectors(x, [f.x.array for f in functions], maps)
    else:
        fem_petsc.assign(functions, x)
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)


def contains(V: fem.FunctionSpace, bc: fem.DirichletBC) -> bool:
    """Whether the Dirichlet condition ``bc`` acts on V (or on a subspace of V)."""
    return V._cpp_object.contains(bc.function_space)


def cpp_form(cpp_class, pointer, spaces, coefficients, constants, integral_types, mesh,
             subdomains=None):
    """The C++ form of a compiled ufcx form (``pointer``) on ``spaces`` with the data of
    ``coefficients``, ``constants`` (Python objects) and ``subdomains`` ({IntegralType:
    [(id, integration entities)]} of its tagged integrals; none: no subdomain data)."""
    old = DOLFINX_VERSION < (0, 10)
    subdomains = subdomains or {}
    return cpp_class(pointer if old else [int(pointer)], [V._cpp_object for V in spaces],
                     [c._cpp_object for c in coefficients], [c._cpp_object for c in constants],
                     {t: list(subdomains.get(t, [])) for t in integral_types},
                     {} if old else [], mesh._cpp_object)


def interpolation_points(V: fem.FunctionSpace):
    """The reference points at which V's element interpolates."""
    points = V.element.interpolation_points
    return points() if callable(points) else points


def geometry_dofmap(mesh):
    """The geometry's cell-to-node map of a mesh of one cell type."""
    geometry = mesh.geometry
    return geometry.dofmaps[0] if hasattr(geometry, "dofmaps") else geometry.dofmap


def real_space(mesh, shape: tuple[int, ...] = ()) -> fem.FunctionSpace:
    """A real space: ``prod(shape)`` global unknowns, constant on the whole mesh."""
    if _BLOCK_ASSEMBLERS:
        import scifem
        # scifem 0.6 creates the global dofs collectively on COMM_WORLD: on another
        # communicator it would hang.
        if MPI.Comm.Compare(mesh.comm, MPI.COMM_WORLD) not in (MPI.IDENT, MPI.CONGRUENT):
            raise ValueError("a real space (the uniform variant) needs a mesh on "
                             "MPI.COMM_WORLD with DOLFINx 0.9 (scifem 0.6 creates its "
                             "global unknowns collectively on COMM_WORLD)")
        return scifem.create_real_functionspace(mesh, shape)
    import basix.ufl
    element = basix.ufl.real_element(mesh.basix_cell(), value_shape=tuple(shape),
                                     dtype=mesh.geometry.x.dtype)
    return fem.functionspace(mesh, element)


def interval_components(comm, nodes, cells) -> dolfinx.mesh.Mesh:
    """An interval mesh of several components: node coordinates (n,) and cells (m, 2) of
    vertex indices, given on rank 0 in order along each component, and distributed in
    contiguous pieces (contiguous_parts), ghosted across shared facets as
    ``create_interval``."""
    import basix.ufl
    import numpy as np
    import ufl
    domain = ufl.Mesh(basix.ufl.element("Lagrange", "interval", 1, shape=(1,)))
    if comm.rank == 0:
        x, c = np.asarray(nodes, float).reshape(-1, 1), np.asarray(cells, np.int64)
    else:
        x, c = np.zeros((0, 1)), np.zeros((0, 2), dtype=np.int64)
    owners = contiguous_parts(c, comm.size)
    ghosts = dolfinx.mesh.GhostMode.shared_facet

    def part(_comm, _nparts, graph, ghosting):
        """Each local cell's owner, then (ghosting) the other owners of its neighbours."""
        links = [[owners[i]] + (sorted({owners[j] for j in graph.links(i)} - {owners[i]})
                                if ghosting else []) for i in range(graph.num_nodes)]
        offsets = np.cumsum([0] + [len(row) for row in links], dtype=np.int32)
        return dolfinx.cpp.graph.AdjacencyList_int32(
            np.array([r for row in links for r in row], dtype=np.int32), offsets)

    if comm.size == 1:
        partitioner = dolfinx.mesh.create_cell_partitioner(ghosts, *(() if _BLOCK_ASSEMBLERS
                                                                     else (2,)))
    else:
        partitioner = dolfinx.cpp.mesh.create_cell_partitioner(
            part, ghosts, *(() if _BLOCK_ASSEMBLERS else (2,)))
    if _BLOCK_ASSEMBLERS:
        return dolfinx.mesh.create_mesh(comm, c, x, domain, partitioner=partitioner)
    return dolfinx.mesh.create_mesh(comm, c, domain, x, partitioner=partitioner)


def contiguous_parts(cells, n_parts: int):
    """The part of each cell (m, 2) of a mesh whose components are runs of consecutive
    cells: n_parts runs of nearly equal length, each cut moved to its component's end
    where it would leave fewer than 2 cells of the component on one side (a rank with
    one cell of a component cannot hold its Dirichlet dofs: fem/assembly.py)."""
    import numpy as np
    m = len(cells)
    breaks = [0] + [i for i in range(1, m) if cells[i][0] != cells[i - 1][1]] + [m]
    cuts = []
    for k in range(1, n_parts):
        cut = round(k * m / n_parts)
        b0 = max(b for b in breaks if b <= cut)
        b1 = min(b for b in breaks if b >= cut)
        if 0 < cut - b0 < 2 or 0 < b1 - cut < 2:
            cut = b0 if cut - b0 <= b1 - cut else b1
        cuts.append(cut)
    return np.searchsorted(np.array(cuts), np.arange(m), side="right")


def linear_problem(a, L, bcs, u: fem.Function, petsc_options: dict):
    """dolfinx.fem.petsc.LinearProblem under a fresh options prefix."""
    if _BLOCK_ASSEMBLERS:
        return fem_petsc.LinearProblem(a, L, bcs=bcs, u=u, petsc_options=petsc_options)
    return fem_petsc.LinearProblem(a, L, bcs=bcs, u=u, petsc_options=petsc_options,
                                   petsc_options_prefix=f"dolfin_rod_lp{next(_prefixes)}_")
