"""Fields along the rod, sampled on every rank and gathered on rank 0 in the order of s.

A model's ``observables()`` (UFL expressions of the current state: centre line,
directors, strains, forces, dissipation rate, ...) are evaluated at the vertices
(*point* fields: continuous ones such as the centre line and the directors) and at the
cell midpoints (*cell* fields: the strains of the 1-point Gauss rule and everything
computed from them) of the owned cells.  Rank 0 receives them sorted by s:

    sampler = LineSampler(model.mesh, model.observables(), point=("centre_line", "d1"))
    sample = sampler.sample()      # collective; a LineSample on rank 0, None elsewhere

A 1-D rod has few unknowns, so gathering them is cheap and the writers (VTX, animation)
run on rank 0 alone, in global s order, with the same output on any number of ranks.

UFL is imported where it is used, not with the module: the painter process (drawing.py)
unpickles the run's LineSamples, and importing UFL there cost 60-150 ms of the pictures'
wall time (issue 30, target 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LineSample", "LineSampler"]


@dataclass
class LineSample:
    """Values along s (rank 0): nodes s_0 < ... < s_M, cells between them; a mesh of
    several rods (rod/layout.py) has one run of nodes per rod, with a gap in s between
    them (``cells``: the two nodes of each cell)."""

    s_nodes: np.ndarray                       # (M + 1,)
    s_cells: np.ndarray                       # (N,) cell midpoints
    point: dict[str, np.ndarray]              # name -> (M + 1, k) or (M + 1,)
    cell: dict[str, np.ndarray]               # name -> (N, k) or (N,)
    cells: np.ndarray | None = None           # (N, 2) node indices; None: i, i + 1

    def segments(self) -> np.ndarray:
        """(N, 2): the nodes of each cell."""
        if self.cells is not None:
            return self.cells
        n = len(self.s_cells)
        return np.column_stack([np.arange(n), np.arange(1, n + 1)])

    def lines(self) -> list[slice]:
        """The runs of consecutive nodes, one per rod (a single rod: all nodes)."""
        seg = self.segments()
        starts = np.concatenate([[0], seg[1:, 0][seg[1:, 0] != seg[:-1, 1]]])
        stops = np.concatenate([starts[1:], [len(self.s_nodes)]])
        return [slice(a, b) for a, b in zip(starts, stops)]


def _components(expr) -> list:
    import ufl
    shape = ufl.shape(expr)
    if shape == ():
        return [expr]
    return [expr[i] for i in range(shape[0])]


def _pack(s, exprs: dict):
    """One UFL vector (s first, then every component) and each field's slice in it."""
    import ufl
    comps, layout = [s], {}
    for name, e in exprs.items():
        c = _components(e)
        layout[name] = (len(comps), len(comps) + len(c), ufl.shape(e) != ())
        comps += c
    return ufl.as_vector(comps), layout


# -- the DOLFINx calls that differ between versions (see dolfin_rod/compat.py) ----------------

def compile_expression(expr, points: np.ndarray):
    """A compiled expression evaluated at reference ``points`` of each cell."""
    from dolfinx import fem
    return fem.Expression(expr, points)


def evaluate_expression(expression, mesh, cells: np.ndarray, n_points: int) -> np.ndarray:
    """Values (cells, points, components) of a compiled vector expression."""
    values = expression.eval(mesh, cells)
    return np.asarray(values).reshape(len(cells), n_points, -1)


# ------------------------------------------------------------------------------------------------


class LineSampler:
    """Evaluates ``observables`` along the rod and gathers them on rank 0 (see module)."""

    def __init__(self, mesh, observables: dict, point: tuple[str, ...]):
        import ufl
        self.mesh, self.comm = mesh, mesh.comm
        s = ufl.SpatialCoordinate(mesh)[0]
        point_exprs = {k: v for k, v in observables.items() if k in point}
        cell_exprs = {k: v for k, v in observables.items() if k not in point}
        p_vec, self.point_layout = _pack(s, point_exprs)
        c_vec, self.cell_layout = _pack(s, cell_exprs)
        self.p_expr = compile_expression(p_vec, np.array([[0.0], [1.0]]))
        self.c_expr = compile_expression(c_vec, np.array([[0.5]]))
        n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self.cells = np.arange(n_owned, dtype=np.int32)

    def sample(self) -> LineSample | None:
        """Collective: the current values, on rank 0 (None on the other ranks)."""
        p = evaluate_expression(self.p_expr, self.mesh, self.cells, 2)
        c = evaluate_expression(self.c_expr, self.mesh, self.cells, 1)[:, 0, :]
        gathered = self.comm.gather((p, c), root=0)
        if gathered is None:
            return None
        p = np.concatenate([g[0] for g in gathered])
        c = np.concatenate([g[1] for g in gathered])
        order = np.argsort(c[:, 0])
        p, c = p[order], c[order]
        left = np.where(p[:, 0, 0] <= p[:, 1, 0], 0, 1)     # the vertex with the smaller s
        rows = np.arange(len(p))
        nodes, cells = _nodes(p[rows, left], p[rows, 1 - left])
        return LineSample(nodes[:, 0], c[:, 0], _unpack(nodes, self.point_layout),
                          _unpack(c, self.cell_layout), cells)


def _nodes(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nodes of cells sorted by s (values at their left and right vertices, s
    first): every left vertex, and the right vertex of the last cell of each run of
    cells that share vertices (one run per rod); and each cell's two node indices."""
    last = np.append(left[1:, 0] != right[:-1, 0], True)
    first_node = np.arange(len(left)) + np.concatenate([[0], np.cumsum(last[:-1])])
    nodes = np.empty((len(left) + int(last.sum()), left.shape[1]))
    nodes[first_node] = left
    nodes[first_node[last] + 1] = right[last]
    return nodes, np.column_stack([first_node, first_node + 1])


def _unpack(values: np.ndarray, layout: dict) -> dict[str, np.ndarray]:
    return {name: (values[:, a:b].copy() if vector else values[:, a].copy())
            for name, (a, b, vector) in layout.items()}
