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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl

__all__ = ["LineSample", "LineSampler"]


@dataclass
class LineSample:
    """Values along s (rank 0): nodes s_0 < ... < s_N, cells between them."""

    s_nodes: np.ndarray                       # (N + 1,)
    s_cells: np.ndarray                       # (N,) cell midpoints
    point: dict[str, np.ndarray]              # name -> (N + 1, k) or (N + 1,)
    cell: dict[str, np.ndarray]               # name -> (N, k) or (N,)


def _components(expr) -> list:
    shape = ufl.shape(expr)
    if shape == ():
        return [expr]
    return [expr[i] for i in range(shape[0])]


def _pack(s, exprs: dict):
    """One UFL vector (s first, then every component) and each field's slice in it."""
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
        nodes = np.concatenate([p[rows, left], p[-1:, 1 - left[-1]]])
        return LineSample(nodes[:, 0], c[:, 0], _unpack(nodes, self.point_layout),
                          _unpack(c, self.cell_layout))


def _unpack(values: np.ndarray, layout: dict) -> dict[str, np.ndarray]:
    return {name: (values[:, a:b].copy() if vector else values[:, a].copy())
            for name, (a, b, vector) in layout.items()}
