"""What the FE models (torsion.TorsionModel, rod.RodModel) share: the ends of the interval
and their measures, coefficients as UFL, Dirichlet conditions recorded by block, the
rate of a prescribed boundary motion, and the assembly of MPI-reduced diagnostics.
"""

from __future__ import annotations

from typing import Callable

import dolfinx
import dolfinx.fem as fem
import dolfinx.la as la
import numpy as np
import ufl
from mpi4py import MPI

from ..checks import ENDS
from . import form_cache, quadrature_rules, shared_mesh

_TAGS = {"start": 1, "end": 2}


def end_coordinate(end: str, length: float) -> float:
    """s of an end: 0 (start) or the length (end)."""
    return 0.0 if end == "start" else float(length)


def at_node(mesh, s_node: float):
    """The marker of the points at s = s_node, to a tolerance relative to the mesh's
    cells (np.isclose's absolute 1e-8 found every node of a rod of length 1e-9 at both
    ends: silently wrong results)."""
    x = np.unique(mesh.geometry.x[:, 0])
    tol = 1e-6 * (np.min(np.diff(x)) if len(x) > 1 else 1.0)
    return lambda p: np.abs(p[0] - s_node) <= tol


def node_dofs(space, s_node: float, component: int | None = None) -> np.ndarray:
    """The dofs of ``space`` (of its ``component``, numbered in ``space``) at the node
    s = s_node (at_node), located once per space of a kept mesh (shared_mesh: the
    entry holds the space, so its id names no other; a second model's supports skip the
    geometric search and the sub-space's collapse)."""
    def locate():
        at = at_node(space.mesh, s_node)
        if component is None:
            return space, fem.locate_dofs_geometrical(space, at)
        sub = space.sub(component)
        return space, fem.locate_dofs_geometrical((sub, sub.collapse()[0]), at)[0]
    return shared_mesh.space(space.mesh, ("node dofs", id(space), s_node, component),
                             locate)[1]


def end_measures(mesh, length: float) -> dict[str, ufl.Measure]:
    """{end: ds restricted to that end point}: point values and point loads in parallel."""
    facets = {end: dolfinx.mesh.locate_entities_boundary(
        mesh, 0, at_node(mesh, end_coordinate(end, length))) for end in ENDS}
    idx = np.concatenate([facets[e] for e in ENDS]).astype(np.int32)
    val = np.concatenate([np.full(len(facets[e]), _TAGS[e]) for e in ENDS]).astype(np.int32)
    order = np.argsort(idx)
    tags = dolfinx.mesh.meshtags(mesh, 0, idx[order], val[order])
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=tags)
    return {end: ds(_TAGS[end]) for end in ENDS}


def vertex_measure(mesh) -> ufl.Measure:
    """dx with the vertex rule: an equation tested with it holds at the nodes (P1)."""
    return ufl.Measure("dx", domain=mesh, metadata={"quadrature_rule": "vertex",
                                                    "quadrature_degree": 1})


def scalar_coefficient(value: float | Callable, mesh, s):
    """A float as a fem.Constant, a callable of s as the UFL expression value(s)."""
    return value(s) if callable(value) else fem.Constant(mesh, float(value))


class NodeValues:
    """Entries (bs components) of dof arrays of one space at fixed nodes s_nodes, from
    their owners, summed over the ranks (one buffer reduction per call)."""

    def __init__(self, space, s_nodes):
        self.bs, self.comm = space.dofmap.index_map_bs, space.mesh.comm
        owned = space.dofmap.index_map.size_local
        self.rows = [(k, d) for k, s_node in enumerate(s_nodes)
                     for d in node_dofs(space, s_node)
                     if d < owned]
        self.shape = (len(s_nodes), self.bs)

    def __call__(self, array: np.ndarray) -> np.ndarray:
        local = np.zeros(self.shape)
        for k, d in self.rows:
            local[k] += array[self.bs * d: self.bs * (d + 1)]
        total = np.empty_like(local)
        self.comm.Allreduce(local, total, op=MPI.SUM)
        return total


class FormSums:
    """Scalar forms assembled together: form k's integrands times component k of a DG0
    test function, so one vector assembly per quadrature rule gives every cell's
    contributions to every form; the owned cells' sums, reduced over the ranks in one
    call (k separate scalar assemblies: k coefficient packings, kernel calls and
    reductions; the rod's four at 16 cells after a step: 105 -> 86 us).  One kernel per
    rule (quadrature_rules.py): FFCx's kernel with the 1-point and another rule gave
    the other rule's terms midpoint values."""

    def __init__(self, mesh, forms: list[ufl.Form], key: str | None = None):
        """``key`` (form_cache.py): the kernels are compiled once per key and bound to
        the data of each later model of the key."""
        V = fem.functionspace(mesh, ("DG", 0, (max(1, len(forms)),)))
        entry = form_cache.lookup(key, mesh.comm)
        objects = form_cache.registry(forms) if key else []
        if entry is not None:
            self.forms = form_cache.bind(entry, objects, V, mesh)
        else:
            w = ufl.TestFunction(V)
            parts = quadrature_rules.one_rule_per_kernel(
                itg.reconstruct(integrand=itg.integrand() * w[k])
                for k, form in enumerate(forms) for itg in form.integrals())
            self.forms = form_cache.jit_form(parts) if parts else []
            if key and parts:
                form_cache.store(key, self.forms, parts, objects)
        self.n, self.comm = len(forms), mesh.comm
        self.owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
        self.vector = la.vector(V.dofmap.index_map, V.dofmap.index_map_bs)

    def __call__(self) -> np.ndarray:
        local = np.zeros(self.n)
        if self.forms:
            b = self.vector
            b.array[:] = 0.0
            for form in self.forms:
                fem.assemble_vector(b.array, form)
            b.scatter_reverse(la.InsertMode.add)     # facet terms of ghost cells
            local += b.array[:self.owned].reshape(-1, self.n).sum(axis=0)
        total = np.empty_like(local)
        self.comm.Allreduce(local, total, op=MPI.SUM)
        return total


def near_nodes(form: ufl.Form, mesh, s_nodes) -> ufl.Form:
    """``form`` with its cell integrals restricted to the cells that touch the nodes at
    ``s_nodes`` (O(1) cells): at those nodes its assembled vector is the full form's,
    since their test functions vanish on every other cell.  A form whose cell integrals
    already have subdomains is returned as it is."""
    cell_integrals = [itg for itg in form.integrals() if itg.integral_type() == "cell"]
    if any(itg.subdomain_data() is not None for itg in cell_integrals):
        return form
    tdim = mesh.topology.dim
    near = [at_node(mesh, s) for s in s_nodes]
    vertices = dolfinx.mesh.locate_entities(
        mesh, 0, lambda x: np.any([at(x) for at in near], axis=0))
    mesh.topology.create_connectivity(0, tdim)
    cells = dolfinx.mesh.compute_incident_entities(mesh.topology, vertices, 0, tdim)
    tags = dolfinx.mesh.meshtags(mesh, tdim, cells, np.ones_like(cells))
    return ufl.Form([itg.reconstruct(subdomain_id=1, subdomain_data=tags)
                     if itg.integral_type() == "cell" else itg for itg in form.integrals()])


def compiled_near_nodes(form: ufl.Form, mesh, s_nodes, key: str | None = None) -> fem.Form:
    """``near_nodes(form, mesh, s_nodes)`` compiled.  With a ``key`` (form_cache.py, e.g.
    from the model's structure as data) its kernel is compiled once per key and bound to
    the data and the cells of each later form of the key (a fit's trials: the reactions'
    forms cost 0.1 s a trial compiled again)."""
    restricted = near_nodes(form, mesh, s_nodes)
    tags = [itg.subdomain_data() for itg in restricted.integrals()
            if itg.integral_type() == "cell"]
    if restricted is form or not tags:        # no cells of its own to bind: compiled
        key = None
    entry = form_cache.lookup(key, mesh.comm)
    objects = form_cache.registry([form])
    if entry is None:
        compiled = form_cache.jit_form(restricted)
        if key:
            form_cache.store(key, [compiled], [restricted], objects, tagged=True)
        return compiled
    cell = fem.IntegralType.cell
    cells = {cell: dolfinx.fem.forms.get_integration_domains(cell, tags[0], [1])}
    return form_cache.bind(entry, objects, form.arguments()[0].ufl_function_space(), mesh,
                           cells)[0]


def nodal_residual(form: fem.Form, nodes: NodeValues) -> np.ndarray:
    """The assembled residual of one block at the nodes: the residual tested with each
    node's unit nodal motions (one assembly)."""
    b = fem.assemble_vector(form)
    b.scatter_reverse(la.InsertMode.add)
    return nodes(b.array)


class FEModel:
    """Base of the FE models: Dirichlet conditions by block, diagnostics by form.

    A subclass calls ``FEModel.__init__(self, mesh)``, creates its conditions with
    ``dirichlet``, sets ``self.problem`` and its diagnostic forms with
    ``set_diagnostic_forms``.
    """

    def __init__(self, mesh):
        self.mesh = mesh
        self.bcs: list[fem.DirichletBC] = []                   # in order of creation
        self.block_bcs: dict[str, list[fem.DirichletBC]] = {}
        self._given_diagnostics: dict | Callable[[], dict] = {}  # UFL by key, or its maker
        self._diagnostic_sums: FormSums | None = None           # compiled on first use

    def dirichlet(self, block: str, space, end: str, length: float, value,
                  component: int | None = None) -> fem.DirichletBC:
        """A Dirichlet condition value at an end on the block's space (or on one
        component of a vector block: a scalar value), recorded in ``block_bcs[block]``
        (e.g. for a sub-problem of some blocks)."""
        return self.dirichlet_at(block, space, end_coordinate(end, length), value, component)

    def dirichlet_at(self, block: str, space, s_end: float, value,
                     component: int | None = None) -> fem.DirichletBC:
        """``dirichlet`` at the node s = s_end (e.g. an end of one rod of several)."""
        dofs = node_dofs(space, s_end, component)
        bc = fem.dirichletbc(value, dofs, space if component is None else space.sub(component))
        self.bcs.append(bc)
        self.block_bcs.setdefault(block, []).append(bc)
        return bc

    def bcs_of(self, block: str) -> list[fem.DirichletBC]:
        """The Dirichlet conditions on one block."""
        return list(self.block_bcs.get(block, []))

    def set_diagnostic_forms(self, forms: dict[str, ufl.Form] | Callable[[], dict]) -> None:
        """The diagnostics' UFL forms, or a function making them (called at the first read
        of ``diagnostic_forms``); compiled at the first ``assembled_diagnostics`` (a model
        that is only stepped never pays for them)."""
        self._given_diagnostics = forms if callable(forms) else dict(forms)
        self._diagnostic_sums = None

    @property
    def diagnostic_forms(self) -> dict[str, ufl.Form]:
        """The diagnostics' UFL forms by key (a function given for them: called now, once)."""
        if callable(self._given_diagnostics):
            self._given_diagnostics = dict(self._given_diagnostics())
        return self._given_diagnostics

    def assembled_diagnostics(self, t: float) -> dict[str, float]:
        """Every diagnostic form at time t (loads set to t), summed over the ranks (one
        assembly: FormSums), and the time."""
        self.problem.set_loads(t)
        if self._diagnostic_sums is None:
            forms = list(self.diagnostic_forms.values())
            structure = self.problem.structure      # the kernel compiled once per structure
            self._diagnostic_sums = FormSums(self.mesh, forms, form_cache.text_key(
                structure, "diagnostic sums", *self.diagnostic_forms) if structure else None)
        d = dict(zip(self.diagnostic_forms, self._diagnostic_sums().tolist()))
        d["time"] = t
        return d

    def pointwise(self, expr) -> np.ndarray:
        """Values of a UFL expression at the cell midpoints (owned cells), (n, ...)."""
        e = fem.Expression(expr, np.array([[0.5]]))
        n = self.mesh.topology.index_map(1).size_local
        return e.eval(self.mesh, np.arange(n, dtype=np.int32)).reshape(n, -1)
