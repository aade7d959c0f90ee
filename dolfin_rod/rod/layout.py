"""Where the rods of a system live on one interval mesh.

Rod k of a system occupies the parameter range [a_k, a_k + L_k] of one DOLFINx interval
mesh with several components (one per rod, no shared vertex): a_0 = 0 and the next rod
starts a gap after the previous one ends (the gap is the longest rod's length, so that
the ends of different rods are far apart in s and every end is found by its
coordinate).  The reference centre line stays X = s e_3 for every rod: a rod's own
arc length is s - a_k, and its place in space is set by the initial displacement x =
r - s e_3 (initial_state.py), so the strains u, v and everything built on them are
those of the single rod.  A single rod is the mesh of [0, L] of ``create_interval``,
and every piecewise quantity below is then the single rod's own object (the same UFL:
the same compiled kernels, bit for bit).

Per-rod node and cell numbering for other modules (outputs, contact): ``rod_of_cells``
(the rod of each local cell), ``span(k)`` (the rod's parameter range).
"""

from __future__ import annotations

from dataclasses import dataclass

import dolfinx
import dolfinx.fem as fem
import numpy as np
import ufl

from ..fem import compat


@dataclass(frozen=True)
class RodLayout:
    """The parameter ranges of the rods of a system (names, lengths, cells per rod;
    ``offsets``: the arc length on its own rod at which each starts, for the pieces of
    a rod split at its kinks, kinks.py; none: 0)."""

    names: tuple[str, ...]
    lengths: tuple[float, ...]
    n_cells: tuple[int, ...]
    offsets: tuple[float, ...] = ()

    @property
    def single(self) -> bool:
        return len(self.lengths) == 1

    @property
    def gap(self) -> float:
        return max(self.lengths)

    @property
    def starts(self) -> tuple[float, ...]:
        a = np.concatenate([[0.0], np.cumsum(np.asarray(self.lengths) + self.gap)[:-1]])
        return tuple(float(v) for v in a)

    def span(self, k: int) -> tuple[float, float]:
        """(a_k, a_k + L_k): rod k's parameter range."""
        a = self.starts[k]
        return a, a + self.lengths[k]

    def mesh(self, comm) -> dolfinx.mesh.Mesh:
        """The interval mesh of all rods (``create_interval`` for a single rod)."""
        if self.single:
            return dolfinx.mesh.create_interval(comm, self.n_cells[0], [0.0, self.lengths[0]])
        nodes = [np.linspace(*self.span(k), n + 1) for k, n in enumerate(self.n_cells)]
        first = np.concatenate([[0], np.cumsum([len(x) for x in nodes])[:-1]])
        cells = np.vstack([f + np.column_stack([np.arange(n), np.arange(1, n + 1)])
                           for f, n in zip(first, self.n_cells)])
        return compat.interval_components(comm, np.concatenate(nodes), cells)

    def rod_of(self, s) -> np.ndarray:
        """The rod each parameter value s belongs to (-1 in a gap)."""
        s = np.asarray(s, float)
        out = np.full(s.shape, -1, dtype=np.int32)
        tol = 1e-12 * max(self.starts[-1] + self.lengths[-1], 1.0)
        for k in range(len(self.lengths)):
            a, b = self.span(k)
            out[(s >= a - tol) & (s <= b + tol)] = k
        return out

    @property
    def rods(self) -> tuple[str, ...]:
        """The user's rods' names: a rod split at its kinks is one rod (its pieces follow
        its first, which has its name, at offsets > 0)."""
        return tuple(name for k, name in enumerate(self.names)
                     if not self.offsets or self.offsets[k] == 0.0)

    def along(self, s) -> tuple[np.ndarray, np.ndarray]:
        """The user's rod (an index into ``rods``) each parameter value s (not in a gap)
        is on, and its arc length on that rod: a rod split at its kinks is one rod, its
        pieces' s continued across the corners."""
        k = self.rod_of(s)
        offsets = np.asarray(self.offsets or (0.0,) * len(self.names))
        owner = np.cumsum(offsets == 0.0) - 1
        return owner[k], np.asarray(s, float) - np.asarray(self.starts)[k] + offsets[k]

    def rod_of_cells(self, mesh) -> np.ndarray:
        """Rod index of each local cell (owned, then ghosts)."""
        tdim = mesh.topology.dim
        n = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
        midpoints = dolfinx.mesh.compute_midpoints(mesh, tdim, np.arange(n, dtype=np.int32))
        return self.rod_of(midpoints[:, 0])


class Pieces:
    """Piecewise quantities on the mesh of a RodLayout: per-rod indicators and
    coefficients that take each rod's own value (see module)."""

    def __init__(self, layout: RodLayout, mesh, s):
        self.layout, self.mesh, self.s = layout, mesh, s
        self._rods = layout.rod_of_cells(mesh)
        self._indicators: dict[int, fem.Function] = {}

    def local_s(self, k: int, offset: bool = True):
        """Rod k's own arc length s - a_k (s itself for a single rod), for a piece of a
        rod + the piece's offset on it (without ``offset``: on the piece)."""
        a = self.layout.starts[k]
        if offset and self.layout.offsets:
            a -= self.layout.offsets[k]
        return self.s if a == 0.0 else self.s - a

    def indicator(self, k: int):
        """1 on rod k, 0 elsewhere (a DG0 field); 1.0 for a single rod."""
        if self.layout.single:
            return 1.0
        if k not in self._indicators:
            chi = fem.Function(fem.functionspace(self.mesh, ("DG", 0)), name=f"rod_{k}")
            chi.x.array[:] = (self._rods == k).astype(float)
            self._indicators[k] = chi
        return self._indicators[k]

    def of_rods(self, g):
        """A field of one real vector holding each rod's values in turn (the uniform
        variant's global natural strains of several rods): rod k's part on its cells."""
        n = len(self.layout.lengths)
        size = ufl.shape(g)[0] // n
        part = (lambda k: g[k]) if size == 1 else \
            (lambda k: ufl.as_vector([g[size * k + i] for i in range(size)]))
        return sum((self.indicator(k) * part(k) for k in range(1, n)),
                   self.indicator(0) * part(0))

    def length(self):
        """Each rod's length on its cells (a float for a single rod)."""
        if self.layout.single:
            return self.layout.lengths[0]
        return self.cellwise(list(self.layout.lengths), (), "rod_length")

    def cellwise(self, values: list, shape: tuple[int, ...], name: str) -> fem.Function:
        """A DG0 field equal to values[k] (an array of ``shape``) on rod k's cells."""
        V = fem.functionspace(self.mesh, ("DG", 0, shape) if shape else ("DG", 0))
        f = fem.Function(V, name=name)
        table = np.array([np.broadcast_to(np.asarray(v, float), shape) for v in values])
        f.x.array[:] = table[self._rods].ravel()
        return f
