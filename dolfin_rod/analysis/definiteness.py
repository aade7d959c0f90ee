"""A fast test of positive definiteness for the stability check (analysis/stability.py):
the symmetric part of a sparse matrix on one rank, as a band, by LAPACK's banded
Cholesky (dpbtrf).

A rod's tangent stiffness couples the dofs of neighbouring nodes only, so in the reverse
Cuthill-McKee order of its pattern it is a band of half-width kd ~ 2 x (dofs per node),
and the banded Cholesky costs O(n kd^2) with no ordering, no symbolic phase and no
solver start-up: a fraction of MUMPS's LDL^T on the small matrices of rods.  Cholesky
succeeds exactly when every pivot of L D L^T in that order is positive; by Sylvester's
law of inertia the matrix then has no negative (and no zero) eigenvalue, the stable
answer of the check, and only an equilibrium that is not positive definite needs the
inertia count (MUMPS).  The rows and columns ``fixed`` (Dirichlet dofs, identity in the
LDL^T of the check: positive pivots) are left out.  The band is built by index maps
from the matrix's CSR values, made once per sparsity pattern.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc
from scipy.linalg import lapack
from scipy.sparse.csgraph import reverse_cuthill_mckee

__all__ = ["BandedCholesky"]


class _BandMap:
    """Where the stored entries of a matrix with a given CSR pattern go in the lower
    band (LAPACK's layout ab[i - j, j], i >= j in the new order), and where their
    transposed entries are: band values of (A + A^T) / 2 by two gathers."""

    def __init__(self, indptr, indices, position: np.ndarray, size: int):
        n = len(indptr) - 1
        rows = np.repeat(np.arange(n), np.diff(indptr))
        i, j = position[rows], position[indices]
        keep = np.flatnonzero((i >= 0) & (j >= 0) & (i >= j))
        self.entries = keep
        self.band = (i[keep] - j[keep]) * size + j[keep]      # in ab.ravel()
        # (r, c) -> data index of (c, r): CSR keys r n + c are sorted (rows, then the
        # sorted columns of a PETSc AIJ row); a transposed entry not stored reads 0
        keys = rows.astype(np.int64) * n + indices
        wanted = indices[keep].astype(np.int64) * n + rows[keep]
        found = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
        self.transposed = np.where(keys[found] == wanted, found, len(keys))
        self.nnz = len(indices)

    def half_sum(self, data: np.ndarray) -> np.ndarray:
        """(a_ij + a_ji) / 2 for the band's entries, in the order of ``band``."""
        padded = np.append(data, 0.0)
        return 0.5 * (padded[self.entries] + padded[self.transposed])


class BandedCholesky:
    """``positive_definite(A, G, zero)``: is (A + A^T)/2 + s G positive definite on
    the dofs not in ``fixed``, s = zero x max |S_ii| / max |G_ii| (the stability check's
    round-off shift; S's Dirichlet diagonal is 1 in that maximum, as in the check's
    LDL^T)?  A and G: sequential AIJ matrices of one layout, G's pattern a part of A's
    (or G None).  The order and band are made at the first call and again when A's
    pattern grows (new segment-contact pairs)."""

    def __init__(self, size: int, fixed: np.ndarray):
        self.free = np.setdiff1d(np.arange(size), fixed)
        self.has_fixed = len(fixed) > 0
        self._maps: dict[int, _BandMap] = {}      # by the id of a matrix's pattern
        self._pattern: tuple | None = None        # (A's nnz, new positions, width)
        self._g: tuple | None = None              # (G's key, band values, max |G_ii|)

    def positive_definite(self, A: PETSc.Mat, G: PETSc.Mat | None, zero: float) -> bool:
        indptr, indices, data = A.getValuesCSR()
        if self._pattern is None or self._pattern[0] != len(indices):
            self._order(indptr, indices)
            self._maps = {}
        _, _, width = self._pattern
        size = len(self.free)
        ab = np.zeros((width, size))
        flat = ab.reshape(-1)
        a = self._map("A", indptr, indices).half_sum(data)
        flat[self._maps["A"].band] = a
        if G is not None:
            g, g_largest = self._metric(G)
            largest = max(np.max(np.abs(flat[:size]), initial=0.0),      # ab[0]
                          1.0 if self.has_fixed else 0.0)
            flat[self._maps["G"].band] += zero * largest / g_largest * g
        _, info = lapack.dpbtrf(ab, lower=1, overwrite_ab=1)
        return info == 0

    def _metric(self, G: PETSc.Mat) -> tuple[np.ndarray, float]:
        """G's band values and largest |G_ii|, kept while G is unchanged (its PETSc
        object state: the metric of rotation increments is assembled once)."""
        key = (G.handle, G.stateGet(), self._pattern[0])
        if self._g is None or self._g[0] != key:
            indptr, indices, data = G.getValuesCSR()
            rows = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
            largest = np.max(np.abs(data[rows == indices]))
            self._g = (key, self._map("G", indptr, indices).half_sum(data), largest)
        return self._g[1], self._g[2]

    def _order(self, indptr, indices) -> None:
        """The reverse Cuthill-McKee order of the free dofs and the band's width."""
        n = len(indptr) - 1
        pattern = sp.csr_matrix((np.ones(len(indices)), indices, indptr), shape=(n, n))
        free = pattern[self.free][:, self.free]
        order = reverse_cuthill_mckee((free + free.T).tocsr(), symmetric_mode=True)
        position = np.full(n, -1)
        position[self.free[order]] = np.arange(len(order))
        rows = np.repeat(np.arange(n), np.diff(indptr))
        i, j = position[rows], position[indices]
        inside = (i >= 0) & (j >= 0)
        width = int(np.max(np.abs(i - j)[inside], initial=0)) + 1
        self._pattern = (len(indices), position, width)

    def _map(self, name: str, indptr, indices) -> _BandMap:
        if name not in self._maps or self._maps[name].nnz != len(indices):
            self._maps[name] = _BandMap(indptr, indices, self._pattern[1], len(self.free))
        return self._maps[name]

